"""The arm as the viewer draws it, for any robot model: points of the kinematic chain from joint values, and joint
values back from the acked tool poses when no state stream gives them.

Pure numpy, no I/O and no Rerun: the chain is the model's URDF chain (``model.urdf_joints``,
:func:`aioadept.robots.urdf.link_transforms`), so the drawn flange is exactly the model's ``flange_matrix`` and
the labels are the URDF's joint names. Which model a run used is in its metadata (:func:`run_model`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from aioadept.geometry import Pose
from aioadept.robots import DEFAULT_MODEL, RobotModel, model
from aioadept.robots.urdf import link_transforms

log = logging.getLogger(__name__)

__all__ = ["chain_labels", "chain_points_mm", "joints_from_pose", "run_model"]


def chain_points_mm(joints_deg: Sequence[float], arm: RobotModel | None = None) -> np.ndarray:
    """N x 3 points (mm, robot base frame) of ``arm`` (default: the Viper s850) for joint values (degrees, mm for a
    prismatic joint): the base, then each joint's axis where the chain reaches it (a joint with no offset from
    the previous one adds none), and a prismatic joint's end of travel; the last point is the flange. A Viper's
    are base, J2 height, shoulder, elbow, the a3 offset, wrist centre and flange; a Cobra's base, J1 top,
    elbow, quill top and flange. Consecutive points are the links to draw."""
    m = model() if arm is None else arm
    table = m.urdf_joints
    if len(joints_deg) != len(table):
        raise ValueError(f"joints_deg: expected {len(table)} values, got {len(joints_deg)}")
    frame = np.eye(4)
    pts = [np.zeros(3)]
    for j, (_p, _c, t_m, rot) in zip(table, link_transforms(m, joints_deg), strict=True):
        if any(j.origin_mm):
            pts.append(frame[:3, :3] @ np.asarray(j.origin_mm, dtype=float) + frame[:3, 3])
        step = np.eye(4)
        step[:3, :3], step[:3, 3] = rot, t_m * 1000.0
        frame = frame @ step
        if j.prismatic:
            pts.append(frame[:3, 3].copy())
    return np.array(pts)


def chain_labels(arm: RobotModel | None = None) -> list[str]:
    """The labels of :func:`chain_points_mm`'s points: ``base``, the URDF joint at each axis point, the child link at
    a prismatic joint's end, and ``flange`` last."""
    m = model() if arm is None else arm
    names = ["base"]
    for j in m.urdf_joints:
        if any(j.origin_mm):
            names.append(j.name)
        if j.prismatic:
            names.append(j.child)
    names[-1] = "flange"
    return names


def joints_from_pose(pose: Pose, seed_deg: Sequence[float] | None = None,
                     arm: RobotModel | None = None) -> tuple[float, ...] | None:
    """Joint values that put the flange of ``arm`` (default: the Viper s850) at ``pose``, nearest to ``seed_deg``
    (the previous joints; default its home), or None when the pose is out of reach or the solution would jump:
    then the viewer keeps the last arm it drew."""
    m = model() if arm is None else arm
    try:
        return tuple(float(v) for v in m.inverse(pose, list(m.home_deg if seed_deg is None else seed_deg), jump=None))
    except Exception:  # noqa: BLE001 - any failure only means "cannot draw the arm for this pose"
        return None


def run_model(metadata: Mapping[str, Any] | None) -> RobotModel:
    """The robot model of a run (``metadata``: a :class:`aioadept.runs.capture.Run`'s, as ``run.json`` keeps it): its
    parameters' ``cell.robot.model`` (the cell file's ``[robot] model``), else the default (runs before robot
    models, or without a cell). An unknown name draws the default too, with a warning naming it: a recording is
    never refused for it."""
    params = (metadata or {}).get("parameters") or {}
    cell = params.get("cell") or {} if isinstance(params, Mapping) else {}
    name = (cell.get("robot") or {}).get("model") if isinstance(cell, Mapping) else None
    try:
        return model(str(name)) if name else model(DEFAULT_MODEL)
    except ValueError as exc:
        log.warning("recording drawn as the %s: %s", DEFAULT_MODEL, exc)
        return model(DEFAULT_MODEL)
