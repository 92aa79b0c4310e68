"""The Viper s850's kinematics as module-level names: :data:`aioadept.robots.viper.VIPER_S850`'s constants and
methods, for the many modules and tests that import the paper's arm by this name.

New code asks the registry (``aioadept.robots.model("viper-s850")``) and calls the model's methods; this module
adds nothing to them. The family's geometry, formulas and docs live in :mod:`aioadept.robots.viper`.
"""

from __future__ import annotations

from aioadept.robots.base import (  # noqa: F401
    DEFAULT_JUMP_LIMIT,
    ConfigRequest,
    Configuration,
    JointLimits,
    JumpLimit,
)
from aioadept.robots.base import matches as _matches  # noqa: F401
from aioadept.robots.base import nearest_equivalent as _nearest_equivalent  # noqa: F401
from aioadept.robots.base import wrap_pi as _wrap_pi  # noqa: F401
from aioadept.robots.viper import (  # noqa: F401
    ELBOW_FREE_DEG,
    SHOULDER_FREE_MM,
    VIPER_S850,
    WRIST_FREE_DEG,
    WRIST_SINGULAR_SIN,
)

MODEL = VIPER_S850

A1_MM, D1_MM, A2_MM, A3_MM, D4_MM, D6_MM = MODEL.a1, MODEL.d1, MODEL.a2, MODEL.a3, MODEL.d4, MODEL.d6
_L3_MM = MODEL.l3
_BETA = MODEL.beta
REACH_MM = MODEL.reach_mm
"""Largest distance of the wrist centre from the J1 axis (about 854.9 mm, the datasheet reach)."""
HOME_JOINTS_DEG: tuple[float, ...] = MODEL.home_deg
"""The paper's init_move joints: upper arm vertical, forearm horizontal, tool pointing down."""
VIPER_S850_LIMITS = MODEL.limits
MAX_JOINT_SPEED_DEG_S: tuple[float, ...] = MODEL.max_speed_deg_s
"""Maximum joint speeds (ARTE). Acceleration limits are modelled as these divided by a ramp time."""

_arm_plane = MODEL.arm_plane
_solutions_rad = MODEL.solutions_rad
_free_configuration = MODEL.free_configuration
configuration = MODEL.configuration
flange_matrix = MODEL.flange_matrix
forward = MODEL.forward
inverse = MODEL.inverse
check_joint_path = MODEL.check_joint_path
