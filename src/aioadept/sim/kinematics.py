"""Compatibility alias: the Viper s850 kinematics moved to :mod:`aioadept.robots.viper_s850` (issue 13), so that
the vision side can use them without importing the simulator. Import from there in new code; this name stays
importable for existing code and re-exports every name, including the private helpers tests use.

Why it stays (issue 24): ``aioadept.sim.kinematics`` is the import path of user code and of some 25 test modules
written before the move; it imports nothing but :mod:`aioadept.robots.viper_s850`, so it costs no dependency.
"""

from aioadept.robots.viper_s850 import *  # noqa: F401,F403
from aioadept.robots.viper_s850 import _BETA, _arm_plane, _solutions_rad  # noqa: F401
