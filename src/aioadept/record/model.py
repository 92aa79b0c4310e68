"""The Viper s850 as the viewer draws it: joint positions of the kinematic chain from joint angles, and joint angles
back from the acked tool poses when no state stream gives them.

Pure numpy, no I/O and no Rerun: the chain follows :mod:`aioadept.sim.kinematics` (the same lengths and the same
V+ joint convention), so the drawn flange is exactly the flange of :func:`~aioadept.sim.kinematics.forward`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from aioadept.geometry import Pose
from aioadept.robots import viper_s850 as kin

__all__ = ["LINK_NAMES", "chain_points_mm", "joints_from_pose"]

LINK_NAMES: tuple[str, ...] = ("base", "j2", "shoulder", "elbow", "forearm", "wrist", "flange")
"""Names of the points :func:`chain_points_mm` returns, base to flange."""


def chain_points_mm(joints_deg: Sequence[float]) -> np.ndarray:
    """7 x 3 points (mm, robot base frame): base, J2 axis height, shoulder (a1), elbow, the a3 offset, wrist centre
    and flange, for joints in degrees. Consecutive points are the links to draw."""
    if len(joints_deg) != 6:
        raise ValueError(f"joints_deg: expected 6 values, got {len(joints_deg)}")
    j1, j2, j3 = (math.radians(v) for v in joints_deg[:3])
    j23 = j2 + j3
    # (radial distance from the J1 axis, height) in the arm plane, as kinematics._arm_plane builds the wrist centre.
    r_elbow = kin.A1_MM + kin.A2_MM * math.cos(j2)
    z_elbow = kin.D1_MM - kin.A2_MM * math.sin(j2)
    r_fore = r_elbow - kin.A3_MM * math.cos(j23)
    z_fore = z_elbow + kin.A3_MM * math.sin(j23)
    r_wrist = r_fore + kin.D4_MM * math.sin(j23)
    z_wrist = z_fore + kin.D4_MM * math.cos(j23)
    plane = [(0.0, 0.0), (0.0, kin.D1_MM), (kin.A1_MM, kin.D1_MM), (r_elbow, z_elbow), (r_fore, z_fore),
             (r_wrist, z_wrist)]
    c, s = math.cos(j1), math.sin(j1)
    pts = np.array([(r * c, r * s, z) for r, z in plane] + [(0.0, 0.0, 0.0)])
    pts[-1] = kin.flange_matrix(joints_deg)[:3, 3]
    return pts


def joints_from_pose(pose: Pose, seed_deg: Sequence[float] = kin.HOME_JOINTS_DEG) -> tuple[float, ...] | None:
    """Joint angles that put the flange at ``pose``, nearest to ``seed_deg`` (the previous joints), or None when the
    pose is out of reach or the solution would jump: then the viewer keeps the last arm it drew."""
    try:
        return tuple(float(v) for v in kin.inverse(pose, list(seed_deg), jump=None))
    except Exception:  # noqa: BLE001 - any failure only means "cannot draw the arm for this pose"
        return None
