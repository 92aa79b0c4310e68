"""The paper's focus application, written once: ``init_move``, ``move_tool_z`` and ``ufloop`` (Semeniuta & Falkman
2019, "Coroutines"), with what they need: the robot and vision protocols, :class:`FocusResult` and
:class:`FocusError`.

The coroutines keep the paper's names and roles and take a :class:`~aioadept.client.RobotClient` and a
:class:`~aioadept.bus.Communicator`. The motions of ``init_move`` are numbers in :mod:`aioadept.robots.paper_cell`
(the virtual camera computes the approach pose from the same ones). :mod:`aioadept.apps.focus` builds on these:
stop events, :class:`~aioadept.apps.focus.FocusParams`, ``ufloop_with_stop``; see its docstring for the safety rule
(no motion after a cancellation, a stop, a lost connection or an ack timeout).
"""

from __future__ import annotations

import asyncio
import logging
import time
from dataclasses import dataclass, field
from typing import Any, Protocol

from aioadept.bus.messages import VISION_REQUEST
from aioadept.commands import SPEED_MAX, SPEED_MIN, MoveJoints, MoveRelJoints, MoveRelTool, MoveTo, MoveToolZ, SetSpeed
from aioadept.cell.schema import Range
from aioadept.errors import AdeptError, CommandAborted, CommandError, FocusError, VisionError
from aioadept.geometry import Pose
from aioadept.robots import paper_cell

log = logging.getLogger("aioadept.apps.focus")

INIT_MOVE = (
    MoveJoints(paper_cell.HOME_JOINTS_DEG),
    MoveRelJoints(paper_cell.REL_JOINTS_DEG),
    MoveRelTool(paper_cell.REL_TOOL),
    MoveRelJoints(paper_cell.REL_JOINTS_2_DEG),
)
"""The paper's ``init_move``: home, then the three motions home -> approach pose."""

HOME_JOINTS_DEG = paper_cell.HOME_JOINTS_DEG
"""The paper's "home" joint configuration: upper arm vertical, forearm horizontal, tool pointing down."""


class Robot(Protocol):
    """What the coroutines need of a robot client (:class:`aioadept.client.RobotClient` has it)."""

    async def cmdexec(self, *commands: Any) -> Any: ...

    async def cmdexec_joined(self, *commands: Any) -> Any: ...


class Vision(Protocol):
    """What the coroutines need of a bus communicator (:class:`aioadept.bus.Communicator` has it)."""

    async def request(self, event_type: str, attributes: dict[str, Any] | None = None, **kw: Any) -> Any: ...


@dataclass(frozen=True, slots=True)
class FocusResult:
    """What a calibration run found."""

    inspection_pose: Pose
    """The pose with the highest sharpness: the inspection-start pose xi_is."""
    approach_pose: Pose
    sharpness: tuple[float, ...]
    """Sharpness after each step; element 0 is at the approach pose."""
    peak_index: int
    delta_z_mm: float
    frame_times_s: tuple[float, ...] = field(default=())
    mode: str = "stepwise"
    """``stepwise`` (:func:`ufloop`) or ``sweep`` (:func:`aioadept.apps.sweep.sweep_focus`)."""
    search_s: float | None = None
    """From the first search motion's start to the focal plane known (stepwise: the fall seen; sweep: the fit)."""
    fitted_offset_mm: float | None = None
    """Sweep: the fitted focal plane along tool z from the approach pose, not rounded to a step."""
    peak_sigma_mm: float | None = None
    """Sweep: the fitted plane's standard uncertainty (mm)."""
    frames: tuple[dict[str, Any], ...] = field(default=())
    """Sweep: each frame's ``offset_mm``, ``sharpness``, mid-exposure ``t_mid_s`` and ``sweep`` index."""
    pose_source: str = ""
    """Sweep: where the frames' positions came from: ``state-stream`` or ``planned-profile`` (acks)."""
    sweep: dict[str, Any] = field(default_factory=dict)
    """Sweep: the plans, the fits, the clock offsets (focus.json's ``sweep``)."""

    @property
    def steps(self) -> int:
        return len(self.sharpness) - 1

    @property
    def peak_offset_mm(self) -> float:
        """Distance along tool z from the approach pose to the inspection-start pose (the fitted plane for a
        sweep, a whole number of steps for the stepwise loop)."""
        if self.fitted_offset_mm is not None:
            return self.fitted_offset_mm
        return self.peak_index * self.delta_z_mm


_SPEED = Range(SPEED_MIN, SPEED_MAX, integer=True, unit="%")
FOCUS_RANGES: dict[str, Range] = {
    "delta_z_mm": Range(0.1, 50.0, unit="mm"),
    "approach_speed": _SPEED,
    "max_steps": Range(1, 1000, integer=True),
    "vision_timeout_s": Range(0.0, lo_open=True, unit="s"),
    "retract_speed": _SPEED,
}
"""The values :func:`ufloop`'s parameters (and :class:`~aioadept.apps.focus.FocusParams`' fields, the cell file's
``[focus]`` table, ``--delta-z``/``--speed``/...) may take, written once. ``delta_z_mm``: below 0.1 mm two steps
differ by little more than the arm's repeatability (about 0.03 mm) and sensor noise decides the peak; 0 or less
never reaches the focal plane (the start or noise was reported as the peak); above 50 mm a step is no search."""


async def init_move(rc: Robot) -> Any:
    """Retract to the home pose, then go to the approach pose (the paper's ``init_move``)."""
    return await rc.cmdexec(*INIT_MOVE)


async def move_tool_z(rc: Robot, appr_speed: int, delta_z: float) -> Any:
    """Set the speed for the next motion and step along tool z, all three messages written at once."""
    return await rc.cmdexec_joined(SetSpeed(appr_speed), MoveToolZ(delta_z))


async def measure(comm: Vision, *, timeout_s: float | None = None) -> tuple[float, dict[str, Any]]:
    """Ask the vision node for the sharpness of the current image. Raises :class:`VisionError` on an error result."""
    resp = await comm.request(VISION_REQUEST, {}, timeout_s=timeout_s)
    attrs = dict(resp.attributes)
    if attrs.get("error"):
        raise VisionError(f"vision node: {attrs['error']}", attributes=attrs)
    if "sharpness" not in attrs:
        raise VisionError("vision response has no 'sharpness' attribute", attributes=attrs)
    return float(attrs["sharpness"]), attrs


async def ufloop(rc: Robot, comm: Vision, delta_z: float, appr_speed: int, *, max_steps: int = 40,
                 vision_timeout_s: float | None = None, retract_speed: int = 25, recorder: Any = None,
                 do_init_move: bool = True, stop_event: asyncio.Event | None = None) -> FocusResult:
    """Approach the focus plane with vision feedback (the paper's ``ufloop``) and return what it found.

    Like the paper: measure, stop when sharpness falls, step back one ``delta_z``. Unlike it: at most ``max_steps``
    steps, and after a failure the loop detects with the robot at rest (vision error or timeout, step limit, an
    ``error`` ack) the robot is sent back to the approach pose before the error propagates. After a cancellation, a
    stop (an ``aborted`` ack, or ``stop_event`` set), a lost connection, an ack timeout or any other error no motion
    is started: the robot stays where it is. Raises :class:`FocusError` (step limit, vision failure) or the robot's
    own error. ValueError before any motion for a value outside its range (:data:`FOCUS_RANGES`: a step of 0 or
    below would report noise or the start as the peak).
    """
    for key, value in (("delta_z_mm", delta_z), ("approach_speed", appr_speed), ("max_steps", max_steps),
                       ("vision_timeout_s", vision_timeout_s), ("retract_speed", retract_speed)):
        if value is not None:
            FOCUS_RANGES[key].check(key, value)
    if do_init_move:
        approach = (await init_move(rc)).pose
    else:
        approach = None
    sharpness: list[float] = []
    frame_times: list[float] = []
    pose: Pose | None = approach
    t_search0: float | None = None  # the first search motion's start (search_s)
    t_known: float | None = None
    try:
        while True:
            if recorder is not None:
                recorder.mark("iteration", len(sharpness))
            try:
                s, attrs = await measure(comm, timeout_s=vision_timeout_s)
            except VisionError as exc:
                raise FocusError(f"step {len(sharpness)}: {exc}", sharpness=sharpness) from exc
            except TimeoutError as exc:
                raise FocusError(f"step {len(sharpness)}: no answer from the vision node ({exc})",
                                 sharpness=sharpness) from exc
            sharpness.append(s)
            frame_times.append(float(attrs.get("frame_t", float("nan"))))
            # The paper's criterion: the first fall in sharpness means the focus plane was passed.
            if len(sharpness) > 1 and sharpness[-1] < sharpness[-2]:
                t_known = time.monotonic()
                break
            if len(sharpness) > max_steps:
                raise FocusError(f"no sharpness peak within {max_steps} steps of {delta_z} mm",
                                 sharpness=sharpness)
            if t_search0 is None:
                t_search0 = time.monotonic()
            pose = (await move_tool_z(rc, appr_speed, delta_z)).pose
        if recorder is not None:
            recorder.mark("retract", len(sharpness))
        pose = (await move_tool_z(rc, appr_speed, -delta_z)).pose  # back to the sharpest position
    except BaseException as exc:
        # Retract only after a failure of our own making with the robot at rest and under our control. A stop
        # (aborted commands), a cancellation (Ctrl-C) or a stop event means someone wants the robot to stay where it
        # is; after a lost connection or a timeout its state is unknown: no new motion then.
        stopped = stop_event is not None and stop_event.is_set()
        ours = isinstance(exc, (FocusError, CommandError)) and not isinstance(exc, CommandAborted)
        retracted = await _retract(rc, approach, retract_speed) if ours and not stopped else False
        if isinstance(exc, FocusError):
            raise FocusError(str(exc), sharpness=sharpness, retracted=retracted) from exc.__cause__
        raise
    peak = len(sharpness) - 2
    if approach is None:
        approach = pose
    search_s = None if t_search0 is None or t_known is None else t_known - t_search0
    return FocusResult(pose, approach, tuple(sharpness), peak, delta_z, tuple(frame_times), search_s=search_s)


async def _retract(rc: Robot, approach: Pose | None, speed: int) -> bool:
    """Best effort: move back to the approach pose. Not shielded: a cancellation (Ctrl-C) ends the retract too, and
    the stop that comes with it halts the motion already written."""
    if approach is None:
        return False
    try:
        await rc.cmdexec(SetSpeed(speed), MoveTo(approach))
    except (AdeptError, OSError) as exc:  # the original error matters more
        log.warning("retract to the approach pose failed: %s", exc)
        return False
    return True
