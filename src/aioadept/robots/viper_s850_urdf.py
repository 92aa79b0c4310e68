"""The Viper s850 as a URDF, and the per-link transforms of the same chain, both from :mod:`.viper_s850`'s constants.

Pure numpy and text, no I/O. :func:`urdf` is the robot description other tools load (Foxglove's URDF panel, Rerun's
MCAP ``urdf`` decoder, ROS); :func:`link_transforms` gives, for joint angles, each link's pose in its parent link,
which ``run.mcap`` records as ``foxglove.FrameTransform`` messages (docs/record.md). Both read the one table
:data:`JOINTS`, so a tool that animates the URDF with recorded joint angles and one that follows the recorded
transforms draw the same arm, and its flange is :func:`~aioadept.robots.viper_s850.flange_matrix` (checked against
an independent URDF library in tests/unit/test_urdf.py).

How the V+ chain (``R = Rz(j1) Ry(j2+j3) Rz(j4) Ry(j5) Rz(j6)``, see :mod:`.viper_s850`) becomes URDF joints, lengths
in mm here and metres in the URDF: J1 turns about z at height d1; J2 about y at the shoulder (a1 out); J3 about y at
the elbow (a2 along the upper arm); J4 about z at the a3 offset (-a3 along the forearm's x); J5 about y at the wrist
centre (d4 up the forearm); J6 about z at the flange (d6 on). Ry(t)·(a2, 0, 0) = (a2 cos t, 0, -a2 sin t) is the
upper arm of ``_arm_plane``, and Ry(j23)·(-a3, 0, d4) its forearm, so no extra fixed rotation is needed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aioadept.robots import viper_s850 as kin

__all__ = ["BASE_LINK", "FLANGE_LINK", "JOINTS", "UrdfJoint", "link_transforms", "quaternion_xyzw", "urdf"]

BASE_LINK = "base_link"
FLANGE_LINK = "flange"


@dataclass(frozen=True, slots=True)
class UrdfJoint:
    """One revolute joint: its name, parent and child link, origin in the parent link (mm) and axis."""

    name: str
    parent: str
    child: str
    origin_mm: tuple[float, float, float]
    axis: tuple[float, float, float]


_Z = (0.0, 0.0, 1.0)
_Y = (0.0, 1.0, 0.0)

JOINTS: tuple[UrdfJoint, ...] = (
    UrdfJoint("joint_1", BASE_LINK, "link_1", (0.0, 0.0, kin.D1_MM), _Z),
    UrdfJoint("joint_2", "link_1", "link_2", (kin.A1_MM, 0.0, 0.0), _Y),
    UrdfJoint("joint_3", "link_2", "link_3", (kin.A2_MM, 0.0, 0.0), _Y),
    UrdfJoint("joint_4", "link_3", "link_4", (-kin.A3_MM, 0.0, 0.0), _Z),
    UrdfJoint("joint_5", "link_4", "link_5", (0.0, 0.0, kin.D4_MM), _Y),
    UrdfJoint("joint_6", "link_5", FLANGE_LINK, (0.0, 0.0, kin.D6_MM), _Z),
)
"""The chain, base to flange: joint i turns by the V+ joint angle Ji (degrees, positive about ``axis``)."""


def _axis_rotation(axis: Sequence[float], angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    if tuple(axis) == _Z:
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # _Y: the only other axis in JOINTS


def link_transforms(joints_deg: Sequence[float]) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """For joints in degrees: ``(parent, child, translation_m, rotation)`` of each link in its parent, base to
    flange (translation in metres, rotation a 3x3 matrix). Composed, they give :func:`kin.flange_matrix`."""
    if len(joints_deg) != 6:
        raise ValueError(f"joints_deg: expected 6 values, got {len(joints_deg)}")
    return [(j.parent, j.child, np.array(j.origin_mm) / 1000.0, _axis_rotation(j.axis, math.radians(q)))
            for j, q in zip(JOINTS, joints_deg, strict=True)]


def quaternion_xyzw(r: np.ndarray) -> tuple[float, float, float, float]:
    """The unit quaternion (x, y, z, w) of a rotation matrix (Shepperd's method: stable for every angle)."""
    m = np.asarray(r, dtype=float)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0.0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = (( m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = (0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s)
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = ((m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = ((m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s)
    n = math.sqrt(sum(v * v for v in q))
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


_LINK_RADIUS_M = 0.04


def _visual(j: UrdfJoint) -> str:
    # The link drawn as a cylinder from its parent joint to this joint (URDF cylinders lie along their z): enough
    # for a viewer to show the arm; the Viper's real meshes are Omron's and not ours to ship.
    x, y, z = (v / 1000.0 for v in j.origin_mm)
    length = math.sqrt(x * x + y * y + z * z)
    if length == 0.0:
        return ""
    pitch = math.atan2(math.hypot(x, y), z)
    yaw = math.atan2(y, x)
    return (f'    <visual>\n      <origin xyz="{x / 2:.6g} {y / 2:.6g} {z / 2:.6g}" rpy="0 {pitch:.9g} {yaw:.9g}"/>\n'
            f'      <geometry><cylinder radius="{_LINK_RADIUS_M:g}" length="{length:.6g}"/></geometry>\n'
            f'      <material name="aioadept_grey"><color rgba="0.75 0.75 0.78 1"/></material>\n    </visual>\n')


def urdf(name: str = "viper_s850") -> str:
    """The URDF text of the Viper s850: links ``base_link``, ``link_1`` .. ``link_5``, ``flange``; revolute
    joints ``joint_1`` .. ``joint_6`` with the software joint limits and speeds of :mod:`.viper_s850`."""
    lim, speeds = kin.VIPER_S850_LIMITS, kin.MAX_JOINT_SPEED_DEG_S
    # Each parent link carries the visual of the segment leading to its child joint.
    visuals = {j.parent: _visual(j) for j in JOINTS}
    links = [BASE_LINK] + [j.child for j in JOINTS]
    out = ['<?xml version="1.0"?>',
           f'<!-- Generated by aioadept.robots.viper_s850_urdf from the kinematic constants of '
           f'aioadept.robots.viper_s850 (a1={kin.A1_MM:g} d1={kin.D1_MM:g} a2={kin.A2_MM:g} a3={kin.A3_MM:g} '
           f'd4={kin.D4_MM:g} d6={kin.D6_MM:g} mm). Joint angles are the V+ joint angles. -->',
           f'<robot name="{name}">']
    for link in links:
        body = visuals.get(link, "")
        out.append(f'  <link name="{link}">\n{body}  </link>' if body else f'  <link name="{link}"/>')
    for i, j in enumerate(JOINTS):
        x, y, z = (v / 1000.0 for v in j.origin_mm)
        out.append(
            f'  <joint name="{j.name}" type="revolute">\n'
            f'    <parent link="{j.parent}"/>\n    <child link="{j.child}"/>\n'
            f'    <origin xyz="{x:.9g} {y:.9g} {z:.9g}" rpy="0 0 0"/>\n'
            f'    <axis xyz="{j.axis[0]:g} {j.axis[1]:g} {j.axis[2]:g}"/>\n'
            f'    <limit lower="{math.radians(lim.min_deg[i]):.9g}" upper="{math.radians(lim.max_deg[i]):.9g}" '
            f'effort="0" velocity="{math.radians(speeds[i]):.9g}"/>\n'
            f'  </joint>')
    out.append('</robot>\n')
    return "\n".join(out)
