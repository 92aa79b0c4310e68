"""The Viper s850's URDF and link transforms (:mod:`aioadept.robots.urdf` for any model): ``run.mcap``,
``aioadept ros2`` and tests import these names."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from aioadept.robots import urdf as _urdf
from aioadept.robots.base import UrdfJoint
from aioadept.robots.urdf import BASE_LINK, FLANGE_LINK, quaternion_xyzw
from aioadept.robots.viper import VIPER_S850

__all__ = ["BASE_LINK", "FLANGE_LINK", "JOINTS", "UrdfJoint", "link_transforms", "quaternion_xyzw", "urdf"]

JOINTS: tuple[UrdfJoint, ...] = VIPER_S850.urdf_joints
"""The chain, base to flange: joint i turns by the V+ joint angle Ji (degrees, positive about ``axis``)."""


def link_transforms(joints_deg: Sequence[float]) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """:func:`aioadept.robots.urdf.link_transforms` of the Viper s850."""
    return _urdf.link_transforms(VIPER_S850, joints_deg)


def urdf(name: str = "viper_s850") -> str:
    """:func:`aioadept.robots.urdf.urdf` of the Viper s850."""
    return _urdf.urdf(VIPER_S850, name)
