"""Camera-to-robot calibration as an application: move the tool (carrying an ArUco marker) through a set of poses in
front of the fixed camera, ask the part locator node for the marker's image corners at each, and estimate where the
camera is in the robot base frame (:func:`aioadept.vision.calibration.calibrate_eye_to_hand`).

Composed like the focus application: a :class:`~aioadept.client.RobotClient` moves (``move_to`` + ``break``: each
view is taken with the arm at rest, and the tool pose used is the one the robot acknowledged, not the one asked
for), a :class:`~aioadept.bus.Communicator` asks the node (``LocateRequest`` with ``marker``, ``marker_mm`` and
``corners = 1``). Safety: every pose is checked before the first motion (:func:`check_poses`); after a
cancellation, a lost connection, a robot error or a failed vision request nothing more is moved.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aioadept.bus.located import LOCATE_REQUEST, parts_from_attributes
from aioadept.geometry import Pose
from aioadept.vision.calibration import CameraCalibration, MarkerView, calibrate_eye_to_hand
from aioadept.errors import CalibrationError

log = logging.getLogger(__name__)


def calibration_poses(centre: Pose, n: int = 12, *, spread_mm: float = 60.0, tilt_deg: float = 20.0,
                      turn_deg: float = 60.0, seed: int = 0) -> list[Pose]:
    """``n`` tool poses around ``centre`` (tool pointing down: pitch 180): positions within ``spread_mm`` in x and y
    and half that in z, the tool turned by up to ``turn_deg`` about its axis and tilted by up to ``tilt_deg``. The
    estimate needs rotations about at least two different axes; these vary all three. Deterministic (``seed``)."""
    if n < 3:
        raise CalibrationError(f"n = {n}: the calibration needs at least 3 poses")
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        dx, dy = rng.uniform(-spread_mm, spread_mm, 2)
        dz = rng.uniform(-spread_mm / 2, spread_mm / 2)
        out.append(Pose(centre.x + dx, centre.y + dy, centre.z + dz, centre.yaw + rng.uniform(-turn_deg, turn_deg),
                        centre.pitch + rng.uniform(-tilt_deg, tilt_deg), centre.roll + rng.uniform(-turn_deg,
                                                                                                     turn_deg)))
    return out


def check_poses(poses: Sequence[Pose], *, min_z_mm: float) -> None:
    """Refuse (before any motion) a pose list with fewer than 3 poses, a non-finite value, or a pose below
    ``min_z_mm`` (the table plus a clearance: the routine never moves the tool towards the table)."""
    if len(poses) < 3:
        raise CalibrationError(f"{len(poses)} poses: the calibration needs at least 3")
    for i, p in enumerate(poses):
        if not all(math.isfinite(v) for v in p):
            raise CalibrationError(f"pose {i} {tuple(p)}: not a finite number")
        if p.z < min_z_mm:
            raise CalibrationError(f"pose {i}: z = {p.z:g} mm is below the lowest allowed {min_z_mm:g} mm (table + "
                                   f"clearance); nothing was moved")


@dataclass(frozen=True, slots=True)
class CalibrationRun:
    """The result: the new calibration, the views used and those skipped (index, why)."""

    calibration: CameraCalibration
    views: tuple[MarkerView, ...]
    skipped: tuple[tuple[int, str], ...]


async def collect_views(robot, vision, poses: Sequence[Pose], *, marker: int, marker_mm: float,  # noqa: ANN001
                        speed: int = 20, vision_timeout_s: float = 5.0) -> tuple[list[MarkerView], list]:
    """Visit each pose (``move_to`` + ``break`` at ``speed`` %) and ask ``vision`` for the marker's corners there.

    A view where the node finds no such marker is skipped (logged); a vision error answer, a timeout or any robot
    error ends the routine at once (raised), with no further motion.
    """
    from aioadept.commands import MoveTo, SetSpeed

    views: list[MarkerView] = []
    skipped: list[tuple[int, str]] = []
    for i, pose in enumerate(poses):
        res = await robot.cmdexec(SetSpeed(speed), MoveTo(pose))
        tool = res.pose  # where the robot says it is, at rest after the break
        answer = await vision.request(LOCATE_REQUEST, {"t_request": time.time(), "marker": marker,
                                                       "marker_mm": float(marker_mm), "corners": 1},
                                      timeout_s=vision_timeout_s)
        if answer.error is not None:
            raise CalibrationError(f"view {i}: the vision node answered: {answer.error}")
        found = [p for p in parts_from_attributes(answer.attributes) if p.marker == marker and p.corners_px]
        if not found:
            skipped.append((i, "marker not seen"))
            log.warning("view %d at %s: marker %d not seen; skipped", i, tool, marker)
            continue
        views.append(MarkerView(tool, np.array(found[0].corners_px, float).reshape(4, 2)))
    return views, skipped


async def calibrate(robot, vision, poses: Sequence[Pose], nominal: CameraCalibration, *,  # noqa: ANN001
                    marker: int, marker_mm: float, speed: int = 20, min_z_mm: float | None = None,
                    vision_timeout_s: float = 5.0) -> CalibrationRun:
    """The whole routine: check the poses, collect the views, estimate. ``nominal`` gives the intrinsics and the
    table (its pose is replaced); ``min_z_mm`` defaults to the table + 100 mm. Raises :class:`CalibrationError`."""
    check_poses(poses, min_z_mm=nominal.table_z_mm + 100.0 if min_z_mm is None else min_z_mm)
    views, skipped = await collect_views(robot, vision, poses, marker=marker, marker_mm=marker_mm, speed=speed,
                                         vision_timeout_s=vision_timeout_s)
    if len(views) < 3:
        raise CalibrationError(f"only {len(views)} of {len(poses)} views saw marker {marker}; at least 3 are "
                               f"needed (is the marker in the camera's view at these poses?)")
    try:
        est = calibrate_eye_to_hand(views, nominal.K, nominal.dist_coeffs, marker_mm)
    except ValueError as exc:
        raise CalibrationError(str(exc)) from None
    cal = nominal.with_pose(est.base_from_camera, rms_px=round(est.rms_px, 4), views=est.views)
    return CalibrationRun(cal, tuple(views), tuple(skipped))


__all__ = ["CalibrationRun", "calibrate", "calibration_poses", "check_poses", "collect_views"]
