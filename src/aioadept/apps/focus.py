"""Focus-plane calibration with vision feedback: the paper's application, as composable coroutines.

The robot holds a calibration object in front of a camera. From the approach pose it steps the tool along its z
axis towards the camera, asks the vision node for the image sharpness after each step, and stops when sharpness
falls: the previous position, one step back, is the inspection-start pose (the paper's xi_is).

The three coroutines of the paper are kept, with the same names and roles (``init_move``, ``move_tool_z``,
``ufloop``), and take a :class:`~aioadept.client.RobotClient` and a :class:`~aioadept.bus.Communicator`. What a
real cell needs on top: a step limit, a clear error when the vision node sees no object, a retract to the approach
pose on any failure, and the found pose returned with the sharpness series. :func:`stop_listener` shows the paper's
"composition of coroutines": a second coroutine that stops the robot when a stop event arrives on the bus.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from aioadept.commands import MoveJoints, MoveRelJoints, MoveRelTool, MoveTo, MoveToolZ, SetSpeed
from aioadept.errors import AdeptError, CommandAborted, VisionError
from aioadept.geometry import Pose

log = logging.getLogger(__name__)

HOME_JOINTS_DEG = (0.0, -90.0, 180.0, 0.0, 90.0, 0.0)
"""The paper's "home" joint configuration: upper arm vertical, forearm horizontal, tool pointing down."""

INIT_MOVE = (
    MoveJoints(HOME_JOINTS_DEG),
    MoveRelJoints([-90, 60, 30, -90, 0, 0]),
    MoveRelTool([40, -25, 185, 0, 0, 0]),
    MoveRelJoints([0, 0, 0, 0, 0, 1.5]),
)
"""The paper's ``init_move``: home, then the three motions home -> approach pose."""

VISION_REQUEST = "VisionRequest"


class FocusError(AdeptError):
    """Focus calibration failed; the robot was sent back to the approach pose (``retracted``)."""

    def __init__(self, message: str, *, sharpness: Sequence[float] = (), retracted: bool = False) -> None:
        super().__init__(message)
        self.sharpness = tuple(sharpness)
        self.retracted = retracted


class Robot(Protocol):
    """What the coroutines need of a robot client (:class:`aioadept.client.RobotClient` has it)."""

    async def cmdexec(self, *commands: Any) -> Any: ...

    async def cmdexec_joined(self, *commands: Any) -> Any: ...


class Vision(Protocol):
    """What the coroutines need of a bus communicator (:class:`aioadept.bus.Communicator` has it)."""

    async def request(self, event_type: str, attributes: dict[str, Any] | None = None, **kw: Any) -> Any: ...


@dataclass(frozen=True, slots=True)
class FocusParams:
    """Parameters of one calibration run (the paper varied speed in {5..100} and delta_z in {1.5, 2.0, 2.5})."""

    delta_z_mm: float = 2.0
    approach_speed: int = 25
    max_steps: int = 40
    """Give up (and retract) after this many z steps without passing the sharpness peak."""
    vision_timeout_s: float = 5.0
    retract_speed: int = 25


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

    @property
    def steps(self) -> int:
        return len(self.sharpness) - 1

    @property
    def peak_offset_mm(self) -> float:
        """Distance along tool z from the approach pose to the inspection-start pose."""
        return self.peak_index * self.delta_z_mm


def _last_pose(results: Any) -> Pose:
    """The pose of the last ack of a cmdexec result (the break after the last motion)."""
    last = results[-1]
    return last.ack.pose


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
                 do_init_move: bool = True) -> FocusResult:
    """Approach the focus plane with vision feedback (the paper's ``ufloop``) and return what it found.

    Like the paper: measure, stop when sharpness falls, step back one ``delta_z``. Unlike it: at most ``max_steps``
    steps, and on any failure (vision error or timeout, robot error, step limit, cancellation) the robot is sent back
    to the approach pose before the error propagates. Raises :class:`FocusError` (step limit, vision failure) or the
    robot's own error.
    """
    if do_init_move:
        approach = _last_pose(await init_move(rc))
    else:
        approach = None
    sharpness: list[float] = []
    frame_times: list[float] = []
    pose: Pose | None = approach
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
                break
            if len(sharpness) > max_steps:
                raise FocusError(f"no sharpness peak within {max_steps} steps of {delta_z} mm",
                                 sharpness=sharpness)
            pose = _last_pose(await move_tool_z(rc, appr_speed, delta_z))
        if recorder is not None:
            recorder.mark("retract", len(sharpness))
        pose = _last_pose(await move_tool_z(rc, appr_speed, -delta_z))  # back to the sharpest position
    except BaseException as exc:
        # A stop (aborted commands) means someone wants the robot to stay where it is: no retract motion then.
        retracted = False if isinstance(exc, CommandAborted) else await _retract(rc, approach, retract_speed)
        if isinstance(exc, FocusError):
            raise FocusError(str(exc), sharpness=sharpness, retracted=retracted) from exc.__cause__
        raise
    peak = len(sharpness) - 2
    if approach is None:
        approach = pose
    return FocusResult(pose, approach, tuple(sharpness), peak, delta_z, tuple(frame_times))


async def _retract(rc: Robot, approach: Pose | None, speed: int) -> bool:
    """Best effort: move back to the approach pose. Shielded, so a cancelled run still retracts."""
    if approach is None:
        return False
    try:
        await asyncio.shield(rc.cmdexec(SetSpeed(speed), MoveTo(approach)))
    except (AdeptError, OSError, asyncio.CancelledError) as exc:  # the original error matters more
        log.warning("retract to the approach pose failed: %s", exc)
        return False
    return True


async def stop_listener(rc: Any, subscriber: Any, *, event_type: str = "StopRequest") -> str:
    """Wait for a stop event on the bus, then stop the robot (the paper's ``listener_coro``).

    ``subscriber`` is an :class:`aioadept.bus.Subscriber` of EPypes events; returns the id of the stop event.
    Compose it with :func:`ufloop` in a TaskGroup: see :func:`ufloop_with_stop`.
    """
    from aioadept.bus.messages import decode_event

    while True:
        _topic, payload = await subscriber.recv()
        etype, eid, _attrs = decode_event(payload)
        if etype == event_type:
            log.warning("stop event %s received: stopping the robot", eid)
            await rc.stop()
            return eid or ""


async def ufloop_with_stop(rc: Any, comm: Vision, subscriber: Any, params: FocusParams,
                           **kw: Any) -> FocusResult:
    """:func:`ufloop` and :func:`stop_listener` as two concurrent coroutines; the first to finish wins.

    A stop event aborts the robot's queued motions; ``ufloop`` then fails with the abort and retracts.
    """
    try:
        async with asyncio.TaskGroup() as tg:
            listener = tg.create_task(stop_listener(rc, subscriber))
            loop_task = tg.create_task(ufloop(rc, comm, params.delta_z_mm, params.approach_speed,
                                              max_steps=params.max_steps, vision_timeout_s=params.vision_timeout_s,
                                              retract_speed=params.retract_speed, **kw))
            loop_task.add_done_callback(lambda _t: listener.cancel())
    except BaseExceptionGroup as group:
        # One coroutine failed (the loop, normally with the abort caused by the stop): raise that error itself.
        if len(group.exceptions) == 1:
            raise group.exceptions[0] from None
        raise
    return loop_task.result()
