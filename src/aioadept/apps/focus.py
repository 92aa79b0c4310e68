"""Focus-plane calibration with vision feedback: the paper's application, as composable coroutines.

The robot holds a calibration object in front of a camera. From the approach pose it steps the tool along its z
axis towards the camera, asks the vision node for the image sharpness after each step, and stops when sharpness
falls: the previous position, one step back, is the inspection-start pose (the paper's xi_is).

The three coroutines of the paper are kept, with the same names and roles (``init_move``, ``move_tool_z``,
``ufloop``), and take a :class:`~aioadept.client.RobotClient` and a :class:`~aioadept.bus.Communicator`. What a
real cell needs on top: a step limit, a clear error when the vision node sees no object, a retract to the approach
pose after a failure the loop detected itself, and the found pose returned with the sharpness series.
:func:`stop_listener` shows the paper's "composition of coroutines": a second coroutine that stops the robot when a
stop event arrives on the bus.

Safety rule of this module: after a cancellation (Ctrl-C), a stop, a lost connection or an ack timeout, no motion
is started, not even the retract: whoever cancelled or stopped wants the arm to stay where it is, and after a lost
connection or timeout nobody knows where it is.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from aioadept.commands import MoveJoints, MoveRelJoints, MoveRelTool, MoveTo, MoveToolZ, SetSpeed
from aioadept.errors import AdeptError, CommandAborted, CommandError, VisionError
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


class FocusStopped(FocusError):
    """A stop event ended the run; the robot was stopped where it was and is NOT moved back."""

    def __init__(self, message: str, *, stop_id: str = "") -> None:
        super().__init__(message)
        self.stop_id = stop_id


class StopFailed(AdeptError):
    """A stop was asked for (a stop event) but the robot did not confirm it: the robot may still be moving.

    Not a :class:`FocusStopped`: the run did not end in a known state. ``__cause__`` is the stop's own error.
    """

    def __init__(self, message: str, *, stop_id: str = "") -> None:
        super().__init__(message)
        self.stop_id = stop_id


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
    own error.
    """
    if do_init_move:
        approach = (await init_move(rc)).pose
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
    return FocusResult(pose, approach, tuple(sharpness), peak, delta_z, tuple(frame_times))


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


async def stop_listener(rc: Any, subscriber: Any, *, event_type: str = "StopRequest",
                        on_stop: Any = None) -> str:
    """Wait for a stop event on the bus, then stop the robot (the paper's ``listener_coro``).

    ``subscriber`` is an :class:`aioadept.bus.Subscriber` of EPypes events; ``on_stop(event_id)`` is called before
    the robot is stopped. Returns the id of the stop event. Compose it with :func:`ufloop`: see
    :func:`ufloop_with_stop`.
    """
    from aioadept.bus.messages import decode_event

    while True:
        _topic, payload = await subscriber.recv()
        try:
            etype, eid, _attrs = decode_event(payload)
        except AdeptError:
            continue  # not an event of ours: a listener must not die of a stranger's message
        if etype == event_type:
            log.warning("stop event %s received: stopping the robot", eid)
            if on_stop is not None:
                on_stop(eid or "")
            await rc.stop()
            return eid or ""


async def ufloop_with_stop(rc: Any, comm: Vision, subscriber: Any, params: FocusParams,
                           **kw: Any) -> FocusResult:
    """:func:`ufloop` and :func:`stop_listener` as two concurrent coroutines (the paper's composition).

    If the loop finishes first, the listener is cancelled and the result returned. If a stop event arrives first,
    the loop is cancelled at once (it writes no further command), the robot is stopped (queued motions aborted), and
    :class:`FocusStopped` is raised once the stop is acked. If the stop fails (error ack, lost connection,
    timeout), :class:`StopFailed` is raised instead: the robot may still be moving, which is not a stop.
    """
    stopped = asyncio.Event()
    stop_ids: list[str] = []

    def on_stop(eid: str) -> None:
        stop_ids.append(eid)
        stopped.set()
        # Cancelled here, before the listener writes the stop: the loop cannot write a motion after it (a message
        # that arrives after a stop runs normally).
        loop_task.cancel()

    loop_task = asyncio.create_task(ufloop(rc, comm, params.delta_z_mm, params.approach_speed,
                                           max_steps=params.max_steps, vision_timeout_s=params.vision_timeout_s,
                                           retract_speed=params.retract_speed, stop_event=stopped, **kw))
    listener = asyncio.create_task(stop_listener(rc, subscriber, on_stop=on_stop))
    try:
        await asyncio.wait({loop_task, listener}, return_when=asyncio.FIRST_COMPLETED)
        if stopped.is_set():
            sid = stop_ids[0]
            try:
                await listener  # the stop itself must be acked before the run counts as stopped
            except (AdeptError, OSError) as exc:
                raise StopFailed(f"stop event {sid!r}: the stop failed ({type(exc).__name__}: {exc}); "
                                 "the robot may still be moving", stop_id=sid) from exc
            await asyncio.gather(loop_task, return_exceptions=True)
            raise FocusStopped(f"stopped by stop event {sid!r}", stop_id=sid)
        if listener.done():
            listener.result()  # the listener failed: raise its error
        return await loop_task
    finally:
        for task in (loop_task, listener):
            task.cancel()
        await asyncio.gather(loop_task, listener, return_exceptions=True)
