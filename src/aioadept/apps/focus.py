"""Focus-plane calibration with vision feedback: the paper's application, as composable coroutines.

The robot holds a calibration object in front of a camera. From the approach pose it steps the tool along its z
axis towards the camera, asks the vision node for the image sharpness after each step, and stops when sharpness
falls: the previous position, one step back, is the inspection-start pose (the paper's xi_is).

The three coroutines of the paper are kept, with the same names and roles (``init_move``, ``move_tool_z``,
``ufloop``, in :mod:`aioadept.apps.paper`), and take a :class:`~aioadept.client.RobotClient` and a
:class:`~aioadept.bus.Communicator`. What a real cell needs on top: a step limit, a clear error when the vision
node sees no object, a retract to the approach pose after a failure the loop detected itself, and the found pose
returned with the sharpness series.
:func:`stop_listener` shows the paper's "composition of coroutines": a second coroutine that stops the robot when a
stop event arrives on the bus.

Safety rule of this module: after a cancellation (Ctrl-C), a stop, a lost connection or an ack timeout, no motion
is started, not even the retract: whoever cancelled or stopped wants the arm to stay where it is, and after a lost
connection or timeout nobody knows where it is.
"""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass
from typing import Any

from aioadept.apps.paper import (
    FOCUS_RANGES,
    FocusResult,
    Vision,
    ufloop,
)
from aioadept.apps.sweep import MODES, SWEEP_RANGES
from aioadept.cell.schema import check_ranges, ranged
from aioadept.errors import AdeptError, FocusStopped, StopFailed

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class FocusParams:
    """Parameters of one calibration run (the paper varied speed in {5..100} and delta_z in {1.5, 2.0, 2.5}).

    Each field's range is :data:`~aioadept.apps.paper.FOCUS_RANGES`' (read with
    :func:`aioadept.cell.schema.range_of`): a value outside it raises ValueError naming the field, so a run never
    starts with a step that cannot find the focal plane (0, negative: the approach pose or noise would be reported
    as the peak) or a speed the robot refuses.
    """

    delta_z_mm: float = ranged(2.0, FOCUS_RANGES["delta_z_mm"])
    """The step along tool +z."""
    approach_speed: int = ranged(25, FOCUS_RANGES["approach_speed"])
    max_steps: int = ranged(40, FOCUS_RANGES["max_steps"])
    """Give up (and retract) after this many z steps without passing the sharpness peak."""
    vision_timeout_s: float = ranged(5.0, FOCUS_RANGES["vision_timeout_s"])
    retract_speed: int = ranged(25, FOCUS_RANGES["retract_speed"])
    mode: str = "stepwise"
    """``stepwise``: the paper's loop (:func:`ufloop`); ``sweep``: one straight-line sweep and a fit
    (:func:`aioadept.apps.sweep.sweep_focus`). The fields below are the sweep's (docs/focus.md)."""
    sweep_range_mm: float = ranged(40.0, SWEEP_RANGES["sweep_range_mm"])
    """The first sweep runs from the approach pose this far along tool +z."""
    depth_of_field_mm: float = ranged(3.0, SWEEP_RANGES["depth_of_field_mm"])
    """The camera's depth of field (the virtual camera's at f/2.8: blur circle <= 2 px over about 3 mm)."""
    max_blur_fraction: float = ranged(0.34, SWEEP_RANGES["max_blur_fraction"])
    """Travel during one exposure, as a fraction of the depth of field: it sets the sweep's speed."""
    sweep_max_speed_mm_s: float = ranged(500.0, SWEEP_RANGES["sweep_max_speed_mm_s"])
    line_speed_mm_s: float = ranged(2000.0, SWEEP_RANGES["line_speed_mm_s"])
    """The tool's straight-line speed at 100 % program speed (the robot's setting; ``aioadept sim
    --cartesian-speed``), times the monitor speed."""
    frame_interval_s: float = ranged(0.012, SWEEP_RANGES["frame_interval_s"])
    """A vision request is sent this often while the tool moves (a node slower than that queues them)."""
    max_peak_sigma_mm: float = ranged(0.1, SWEEP_RANGES["max_peak_sigma_mm"])
    """A fit less certain than this is followed by a slower sweep over ``fine_range_mm``."""
    fine_range_mm: float = ranged(12.0, SWEEP_RANGES["fine_range_mm"])
    fine_speed_factor: float = ranged(0.5, SWEEP_RANGES["fine_speed_factor"])
    """The fine sweep's speed as a fraction of the first sweep's."""
    max_sweeps: int = ranged(4, SWEEP_RANGES["max_sweeps"])
    """Give up (and retract) after this many sweeps without a bracketed, certain peak."""

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode = {self.mode!r}: expected one of {', '.join(MODES)}")
        check_ranges(self)


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
