"""The paper's cell (Semeniuta & Falkman 2019, "Coroutines"): the motions of ``init_move`` as numbers, written once.

``aioadept.apps.paper`` sends them as commands; the virtual camera (``aioadept.vision.virtual_camera``) computes the
approach pose they reach; the synthetic runs (``aioadept.analysis.synthetic``) replay their message pattern. They
live here, below all three, so vision does not import the apps.
"""

from __future__ import annotations

from aioadept.robots.viper import VIPER_S850

HOME_JOINTS_DEG: tuple[float, ...] = VIPER_S850.home_deg
"""The paper's arm at home: where ``init_move`` starts."""

__all__ = ["HOME_JOINTS_DEG", "REL_JOINTS_2_DEG", "REL_JOINTS_DEG", "REL_TOOL"]

REL_JOINTS_DEG: tuple[float, ...] = (-90.0, 60.0, 30.0, -90.0, 0.0, 0.0)
"""init_move's relative joint move from home (MoveRelJoints)."""
REL_TOOL: tuple[float, ...] = (40.0, -25.0, 185.0, 0.0, 0.0, 0.0)
"""init_move's tool-frame move (MoveRelTool), mm and degrees."""
REL_JOINTS_2_DEG: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 1.5)
"""init_move's last motion: the final J6 rotation that reaches the approach pose (MoveRelJoints)."""
