"""Any robot model as a URDF, and the per-link transforms of the same chain, both from the model's joint table.

Pure numpy and text, no I/O. :func:`urdf` is the robot description other tools load (Foxglove's URDF panel, Rerun's
MCAP ``urdf`` decoder, ROS); :func:`link_transforms` gives, for joint values, each link's pose in its parent link,
which ``run.mcap`` records as ``foxglove.FrameTransform`` messages (docs/record.md). Both read the one table
``model.urdf_joints`` (:class:`~aioadept.robots.base.UrdfJoint`), so a tool that animates the URDF with recorded
joint values and one that follows the recorded transforms draw the same arm, and its flange is the model's
``flange_matrix`` (checked against an independent URDF library in tests/unit/test_robot_models.py).

Lengths are mm in the models and metres in the URDF; a revolute joint's value is the V+ joint angle in degrees
(radians in the URDF), a prismatic joint's (a SCARA's J3) mm (metres in the URDF).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from aioadept.robots.base import UrdfJoint

__all__ = ["BASE_LINK", "FLANGE_LINK", "link_transforms", "quaternion_xyzw", "rotation", "urdf"]

BASE_LINK = "base_link"
FLANGE_LINK = "flange"


def rotation(axis: Sequence[float], angle_rad: float) -> np.ndarray:
    """The rotation by ``angle_rad`` about the unit vector ``axis`` (Rodrigues)."""
    x, y, z = (float(v) for v in axis)
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def _rpy(rpy: Sequence[float]) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw: Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    return rotation((0, 0, 1), y) @ rotation((0, 1, 0), p) @ rotation((1, 0, 0), r)


def link_transforms(model: Any, joints: Sequence[float]) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """For joint values (degrees; mm for a prismatic joint): ``(parent, child, translation_m, rotation)`` of each
    link in its parent, base to flange (translation in metres, rotation a 3x3 matrix). Composed, they give the
    model's ``flange_matrix``."""
    table: tuple[UrdfJoint, ...] = model.urdf_joints
    if len(joints) != len(table):
        raise ValueError(f"joints: expected {len(table)} values, got {len(joints)}")
    out = []
    for j, q in zip(table, joints, strict=True):
        fixed = _rpy(j.origin_rpy)
        t = np.array(j.origin_mm) / 1000.0
        if j.prismatic:
            out.append((j.parent, j.child, t + fixed @ (np.array(j.axis) * (q / 1000.0)), fixed))
        else:
            out.append((j.parent, j.child, t, fixed @ rotation(j.axis, math.radians(q))))
    return out


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
    # for a viewer to show the arm; the real meshes are Omron's and not ours to ship.
    x, y, z = (v / 1000.0 for v in j.origin_mm)
    length = math.sqrt(x * x + y * y + z * z)
    if length == 0.0:
        return ""
    pitch = math.atan2(math.hypot(x, y), z)
    yaw = math.atan2(y, x)
    return (f'    <visual>\n      <origin xyz="{x / 2:.6g} {y / 2:.6g} {z / 2:.6g}" rpy="0 {pitch:.9g} {yaw:.9g}"/>\n'
            f'      <geometry><cylinder radius="{_LINK_RADIUS_M:g}" length="{length:.6g}"/></geometry>\n'
            f'      <material name="aioadept_grey"><color rgba="0.75 0.75 0.78 1"/></material>\n    </visual>\n')


def urdf(model: Any, name: str | None = None) -> str:
    """The URDF text of ``model``: links ``base_link`` .. ``flange``, one joint per axis (``joint_1`` ..) with the
    model's software joint limits and speeds. ``name``: the robot's name (default: the model's, with ``_``)."""
    table: tuple[UrdfJoint, ...] = model.urdf_joints
    lim, speeds = model.limits, model.max_speed_deg_s
    # Each parent link carries the visual of the segment leading to its child joint.
    visuals = {j.parent: _visual(j) for j in table}
    links = [BASE_LINK] + [j.child for j in table]
    robot = name if name is not None else model.name.replace("-", "_")
    out = ['<?xml version="1.0"?>',
           f'<!-- Generated by aioadept.robots.urdf from the kinematic constants of the {model.name} '
           f'({model.describe()}). Joint values are the V+ joint values. -->',
           f'<robot name="{robot}">']
    for link in links:
        body = visuals.get(link, "")
        out.append(f'  <link name="{link}">\n{body}  </link>' if body else f'  <link name="{link}"/>')
    for i, j in enumerate(table):
        x, y, z = (v / 1000.0 for v in j.origin_mm)
        # prismatic: mm -> m; revolute: deg -> rad
        unit = (lambda v: v / 1000.0) if j.prismatic else math.radians
        out.append(
            f'  <joint name="{j.name}" type="{"prismatic" if j.prismatic else "revolute"}">\n'
            f'    <parent link="{j.parent}"/>\n    <child link="{j.child}"/>\n'
            f'    <origin xyz="{x:.9g} {y:.9g} {z:.9g}" rpy="{" ".join(f"{a:.17g}" for a in j.origin_rpy)}"/>\n'
            f'    <axis xyz="{j.axis[0]:g} {j.axis[1]:g} {j.axis[2]:g}"/>\n'
            f'    <limit lower="{unit(lim.min_deg[i]):.9g}" upper="{unit(lim.max_deg[i]):.9g}" '
            f'effort="0" velocity="{unit(speeds[i]):.9g}"/>\n'
            f'  </joint>')
    out.append('</robot>\n')
    return "\n".join(out)
