"""Focus calibration in one sweep (``aioadept focus --mode sweep``): a continuous straight line along the tool axis,
frames triggered at a fixed interval while the tool moves, each frame placed on the line by the robot state at its
mid-exposure, and a fit of sharpness against position.

Where it sits: beside the paper's stepwise loop (:func:`aioadept.apps.paper.ufloop`, still the default and the
reference), with the same robot and vision protocols and the same :class:`~aioadept.apps.paper.FocusResult`. Data
path::

    init_move -> approach pose A
    MoveToS(A:TRANS(0,0,to)) at speed v   ||  every frame_interval_s: VisionRequest -> (frame_t, exposure, sharpness)
    robot.state samples (wall time, pose)  ->  offset along A's z at each frame's mid-exposure (clocks aligned)
    fit_peak(offsets, sharpness) -> peak +- sigma; not bracketed: extend; sigma too large: slower, narrower sweep
    MoveToS(A:TRANS(0,0,peak))

The pure parts take numbers and return numbers: the plans in :mod:`aioadept.apps.sweep_plan`, the fit and the
frames' positions in :mod:`aioadept.apps.sweep_model`; :func:`sweep_focus` is the coroutine that runs a sweep.
docs/focus.md explains the method, its assumptions and when the stepwise loop is the better choice.

Safety as in :mod:`aioadept.apps.paper`: after a stop, a cancellation, a lost connection or an ack timeout no motion
is started; only a failure this module detects itself with the robot at rest (no peak found, no frames) retracts to
the approach pose.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any


from aioadept.apps.paper import FocusResult, Robot, Vision, _retract, init_move
from aioadept.errors import FocusError
from aioadept.apps.sweep_model import (PeakFit, StateTrack, _finite, axis_offset_mm, clock_offset, fit_peak,
                                      profile_offset)
from aioadept.apps.sweep_plan import SweepPlan, check_sweep, max_reach_mm, next_plan, plan_sweep
from aioadept.commands import Break, MoveToS, SetSpeed
from aioadept.cell.schema import Range
from aioadept.errors import CommandAborted, CommandError
from aioadept.geometry import Pose

log = logging.getLogger("aioadept.apps.sweep")

MODES = ("stepwise", "sweep")
"""``[focus] mode``: the paper's stepwise loop (default) or one sweep."""

SWEEP_RANGES: dict[str, Range] = {
    "sweep_range_mm": Range(1.0, 200.0, unit="mm"),
    "depth_of_field_mm": Range(0.0, 100.0, lo_open=True, unit="mm"),
    "max_blur_fraction": Range(0.0, 1.0, lo_open=True),
    "sweep_max_speed_mm_s": Range(0.0, 2000.0, lo_open=True, unit="mm/s"),
    "line_speed_mm_s": Range(1.0, 10000.0, unit="mm/s"),
    "frame_interval_s": Range(0.001, 1.0, unit="s"),
    "max_peak_sigma_mm": Range(0.0, 10.0, lo_open=True, unit="mm"),
    "fine_range_mm": Range(1.0, 100.0, unit="mm"),
    "fine_speed_factor": Range(0.0, 1.0, lo_open=True),
    "max_sweeps": Range(1, 10, integer=True),
}
"""The sweep's ``[focus]`` values, written once (``FocusParams`` fields carry them; ``--help`` and the cell file
check read them here). ``depth_of_field_mm`` x ``max_blur_fraction`` is the longest travel allowed during one
exposure; ``line_speed_mm_s`` is what 100 % program speed means for a straight line on the robot (the sim's
``--cartesian-speed``, 2000 by default)."""

IN_FLIGHT = 2
"""Vision requests outstanding at once during a sweep (see :func:`_one_sweep`)."""


# ------------------------------------------------------------------------------------------------ the coroutine
@dataclass
class SweepFrame:
    """One frame of a sweep: its mid-exposure (local epoch s), sharpness and, once known, its offset (mm)."""

    sweep: int
    t_mid_s: float
    sharpness: float
    offset_mm: float = math.nan
    t_send_s: float = 0.0
    t_recv_s: float = 0.0
    frame_t_s: float = 0.0
    exposure_s: float = 0.0
    readout_s: float = 0.0

    def as_dict(self) -> dict[str, Any]:
        return {"sweep": self.sweep, "t_mid_s": self.t_mid_s, "offset_mm": _finite(self.offset_mm),
                "sharpness": self.sharpness}


@dataclass
class SweepRun:
    """What :func:`sweep_focus` collected (returned inside :class:`FocusResult` as plain data)."""

    frames: list[SweepFrame] = field(default_factory=list)
    plans: list[SweepPlan] = field(default_factory=list)
    fits: list[PeakFit] = field(default_factory=list)
    t_motion0_s: float | None = None
    """Local epoch time the first sweep motion was written (search_s starts there)."""
    vision_offset_s: float = 0.0
    vision_offset_bounds_s: tuple[float, float] = (-math.inf, math.inf)
    errors: int = 0
    first_error: str = ""
    timing_sigma_mm: float = 0.0
    """Planned profile only: how far a frame's position may be off through the ack times (added to the fit's
    uncertainty in the result; another sweep cannot reduce it)."""


class StateFeed:
    """A robot state subscription filling a :class:`StateTrack` (offsets from ``approach``), in a task of its own.

    ``await feed.start(endpoint)`` subscribes and waits up to ``wait_s`` for a first sample; False when none came
    (no stream at that address): the caller then uses the planned profile."""

    def __init__(self, approach: Pose, *, curve: Any = None) -> None:
        self.approach = approach
        self.track = StateTrack()
        self.curve = curve
        self._sub: Any = None
        self._task: asyncio.Task[None] | None = None
        self._first = asyncio.Event()

    async def start(self, endpoint: str, *, wait_s: float = 1.0) -> bool:
        from aioadept.bus.messages import ROBOT_STATE_TOPIC
        from aioadept.bus.pubsub import Subscriber

        self._sub = Subscriber(endpoint, topics=(ROBOT_STATE_TOPIC,), curve=self.curve)
        self._task = asyncio.create_task(self._run())
        try:
            async with asyncio.timeout(wait_s):
                await self._first.wait()
        except TimeoutError:
            return False
        return True

    async def _run(self) -> None:
        from aioadept.bus.messages import RobotState

        while True:
            _topic, payload = await self._sub.recv()
            now = time.time()
            try:
                st = RobotState.from_bytes(payload)
            except Exception:  # a stranger's message must not end the feed
                continue
            self.track.add(st.wall_time_s, now, axis_offset_mm(self.approach, st.pose))
            self._first.set()

    async def wait_covering(self, t_local: float, timeout_s: float = 0.5) -> bool:
        deadline = time.monotonic() + timeout_s
        while not self.track.covers(t_local):
            if time.monotonic() > deadline:
                return False
            await asyncio.sleep(0.002)
        return True

    async def aclose(self) -> None:
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
        if self._sub is not None:
            self._sub.close()


async def sweep_focus(rc: Robot, comm: Vision, params: Any, *, exposure_ms: float,
                      state_endpoint: str | None = None, state_curve: Any = None,
                      vision_timeout_s: float | None = None, recorder: Any = None, do_init_move: bool = True,
                      stop_event: asyncio.Event | None = None, ramp_s: float = 0.1,
                      time_scale: float = 1.0) -> FocusResult:
    """Find the focal plane with sweeps (module docstring) and move there; return the :class:`FocusResult`
    (``mode="sweep"``, ``fitted_offset_mm``, ``peak_sigma_mm``, ``search_s``, the frames, which pose source).

    ``params``: :class:`~aioadept.apps.focus.FocusParams`; ``exposure_ms``: the camera's (sets the speed);
    ``state_endpoint``: the robot state stream (None or silent: the planned profile and the ack times place the
    frames instead; ``ramp_s`` is the robot's ramp time the profile assumes, in robot time); ``time_scale``: a
    simulated robot's speed-up (:func:`~aioadept.apps.sweep_plan.sweep_speed`; its ramps are that much shorter
    too) when the robot's ``status`` does not report one (:func:`robot_time_scale`). Raises
    :class:`FocusError` (no peak within ``max_sweeps`` sweeps or the reach, no usable frames, no answer from the
    vision node: after the line ended and a retract to the approach pose) or the robot's own error.
    """
    time_scale = await robot_time_scale(rc, time_scale)
    check_sweep(params, exposure_ms, time_scale)
    approach = (await init_move(rc)).pose if do_init_move else None
    if approach is None:
        from aioadept.commands import Here

        approach = (await rc.cmdexec(Here())).pose
    run = SweepRun()
    feed: StateFeed | None = None
    source = "planned-profile"
    t_known: float | None = None
    here_mm = 0.0
    fit: PeakFit | None = None
    try:
        if state_endpoint:
            feed = StateFeed(approach, curve=state_curve)
            if await _start_feed(feed, state_endpoint):
                source = "state-stream"
        plan = plan_sweep(params, exposure_ms, 0.0, min(params.sweep_range_mm, max_reach_mm(params)),
                          time_scale=time_scale)
        while True:
            if stop_event is not None and stop_event.is_set():
                raise asyncio.CancelledError
            run.plans.append(plan)
            if recorder is not None:
                recorder.mark("sweep", len(run.plans) - 1)
            known = await _one_sweep(rc, comm, approach, plan, len(run.plans) - 1, run, feed, source,
                                     params.frame_interval_s, vision_timeout_s, ramp_s, params, time_scale)
            here_mm = plan.to_mm
            fit = fit_peak([f.offset_mm for f in run.frames], [f.sharpness for f in run.frames])
            run.fits.append(fit)
            if known is not None and fit.ok and fit.bracketed and fit.sigma_mm <= params.max_peak_sigma_mm:
                t_known = known  # decided while the robot was still moving (state stream)
            log.info("sweep %d %.1f..%.1f mm at %d %% (tool %.0f mm/s at time scale %g): %s", len(run.plans) - 1,
                     plan.from_mm, plan.to_mm, plan.speed_pct, plan.speed_mm_s, time_scale, fit.summary())
            log.debug("sweep %d fit: %s", len(run.plans) - 1, fit)
            # Without the state stream a finer sweep cannot be placed better than the first (the ack timing, not
            # the frames, limits it): the first bracketed fit stands, its sigma including that timing.
            certain = fit.sigma_mm <= params.max_peak_sigma_mm or source == "planned-profile"
            if fit.ok and fit.bracketed and certain:
                if t_known is None:
                    t_known = time.time()
                break
            if len(run.plans) >= params.max_sweeps:
                raise _no_focal_plane(run, fit, params)
            plan = next_plan(params, exposure_ms, fit, here_mm, time_scale,
                             forward_only=source == "planned-profile", last=plan)
        peak = fit.peak_mm
        target = approach @ Pose(z=peak)
        if recorder is not None:
            recorder.mark("retract", len(run.frames))
        pose = (await rc.cmdexec(SetSpeed(params.approach_speed), MoveToS(target))).pose
    except BaseException as exc:
        stopped = stop_event is not None and stop_event.is_set()
        ours = isinstance(exc, (FocusError, CommandError)) and not isinstance(exc, CommandAborted)
        retracted = await _retract(rc, approach, params.retract_speed) if ours and not stopped else False
        if isinstance(exc, FocusError):
            raise FocusError(str(exc), sharpness=exc.sharpness, retracted=retracted) from exc.__cause__
        raise
    finally:
        if feed is not None:
            await feed.aclose()
    frames = sorted(run.frames, key=lambda f: f.t_mid_s)
    best = max(range(len(frames)), key=lambda k: frames[k].sharpness) if frames else 0
    return FocusResult(
        pose, approach, tuple(f.sharpness for f in frames), best, params.delta_z_mm,
        tuple(f.frame_t_s for f in frames), mode="sweep", fitted_offset_mm=peak,
        peak_sigma_mm=math.hypot(fit.sigma_mm, run.timing_sigma_mm),
        search_s=(t_known - run.t_motion0_s) if run.t_motion0_s is not None and t_known is not None else None,
        frames=tuple(f.as_dict() for f in frames), pose_source=source,
        sweep={"plans": [p.as_dict() for p in run.plans], "fits": [f.as_dict() for f in run.fits],
               "vision_clock_offset_s": run.vision_offset_s,
               "vision_clock_offset_bounds_s": [_finite(b) for b in run.vision_offset_bounds_s],
               "state_delay_s": feed.track.delay_s if feed is not None and len(feed.track) else None,
               "frame_errors": run.errors, "exposure_ms": exposure_ms,
               "timing_sigma_mm": run.timing_sigma_mm})


async def _start_feed(feed: StateFeed, state_endpoint: str) -> bool:
    """Whether the robot state stream answers; if not, the frames are placed by the planned profile (logged)."""
    try:
        if await feed.start(state_endpoint):
            return True
        log.warning("no robot state on %s within 1 s: frames placed by the planned profile", state_endpoint)
    except Exception as exc:  # a bad address must not stop a calibration that can do without it
        log.warning("robot state stream %s: %s; frames placed by the planned profile", state_endpoint, exc)
    return False


def _no_focal_plane(run: SweepRun, fit: PeakFit, params: Any) -> FocusError:
    """The error of a search that ran out of sweeps, saying why the last fit did not settle it."""
    end = "far" if fit.side > 0 else "near"
    why = fit.why or (f"peak not bracketed (sharpness still rising at the {end} end)"
                      if not fit.bracketed else
                      f"peak uncertainty {fit.sigma_mm:.3f} mm above max_peak_sigma_mm "
                      f"{params.max_peak_sigma_mm:g}")
    if run.errors:
        why += f"; the vision node refused {run.errors} frame(s), first: {run.first_error}"
    return FocusError(f"no focal plane after {len(run.plans)} sweep(s): {why}",
                      sharpness=[f.sharpness for f in run.frames])


async def robot_time_scale(rc: Robot, fallback: float) -> float:
    """The robot's time scale as its ``status`` reports it (``ts=``: the Python sim's ``--time-scale``, wherever the
    sim was started), else ``fallback`` (the cell file's ``[robot] time_scale``: the V+ server does not report one).
    A sweep at the wrong scale moves the tool that many times faster or slower than planned and blurs its frames."""
    from aioadept.commands import GetStatus
    from aioadept.errors import RemoteProtocolError
    from aioadept.protocol.robotstatus import parse_status_fields

    try:
        reported = parse_status_fields((await rc.cmdexec(GetStatus())).messages[-1].ack.extra).time_scale
    except (CommandError, RemoteProtocolError) as exc:  # a server without status: its refusal, nothing ran
        log.info("robot time scale %g from the cell file ([robot] time_scale): status: %s", fallback, exc)
        return fallback
    if reported is None:
        log.info("robot time scale %g from the cell file ([robot] time_scale): the robot does not report one",
                 fallback)
        return fallback
    log.info("robot time scale %g, as the robot's status reports it", reported)
    return reported


async def _one_sweep(rc: Robot, comm: Vision, approach: Pose, plan: SweepPlan, index: int, run: SweepRun,
                     feed: StateFeed | None, source: str, interval_s: float, vision_timeout_s: float | None,
                     ramp_s: float, params: Any, time_scale: float = 1.0) -> float | None:
    """Run one sweep: go to its start if the robot is not there, then the line with frames triggered every
    ``interval_s``. Returns the local time the peak became known during the sweep (state stream only), else None."""
    start = approach @ Pose(z=plan.from_mm)
    to = approach @ Pose(z=plan.to_mm)
    here = (await rc.cmdexec(_here())).pose
    if abs(axis_offset_mm(approach, here) - plan.from_mm) > 0.05:
        await rc.cmdexec(SetSpeed(params.approach_speed), MoveToS(start))
    loop = asyncio.get_running_loop()
    epoch_minus_loop = time.time() - loop.time()
    if run.t_motion0_s is None:
        run.t_motion0_s = time.time()
    motion = asyncio.ensure_future(rc.cmdexec_joined(SetSpeed(plan.speed_pct), MoveToS(to, break_move=False),
                                                     Break()))
    frames: list[SweepFrame] = []
    known: list[float] = []

    async def one_frame(t_send: float) -> None:
        try:
            resp = await comm.request("VisionRequest", {}, timeout_s=vision_timeout_s)
        except TimeoutError as exc:
            raise FocusError(f"sweep {index}: no answer from the vision node ({exc})") from exc
        f = _sweep_frame(run, index, dict(resp.attributes), t_send, time.time())
        if f is None:
            return
        frames.append(f)
        if feed is not None and source == "state-stream" and not known and _peak_known(run, frames, feed, params):
            known.append(time.time())

    result = await _frames_during(motion, one_frame, interval_s)
    _place_vision_clock(run, frames)
    if feed is not None and source == "state-stream":
        for f in frames:
            if math.isnan(f.offset_mm) and await feed.wait_covering(f.t_mid_s):
                f.offset_mm = feed.track.at(f.t_mid_s)
    else:
        _place_by_profile(run, frames, result, plan, ramp_s / time_scale, epoch_minus_loop)
    run.frames.extend(frames)
    return known[0] if known else None


async def _frames_during(motion: asyncio.Future[Any], one_frame: Callable[[float], Awaitable[None]],
                         interval_s: float) -> Any:
    """Ask for a frame every ``interval_s`` while ``motion`` runs and return the motion's result. A frame's own
    error stops the asking and is raised once the motion has ended."""
    loop = asyncio.get_running_loop()
    pending: set[asyncio.Task[Any]] = set()
    failed: list[BaseException] = []

    def settled(task: asyncio.Task[Any]) -> None:
        pending.discard(task)
        if not task.cancelled() and task.exception() is not None:
            failed.append(task.exception())  # type: ignore[arg-type]

    try:
        next_t = loop.time()
        while not motion.done():
            # At most IN_FLIGHT requests outstanding: one exposing, one waiting to trigger the moment the camera is
            # free. A deeper queue at a node slower than the interval would only hold frames of the arm at rest.
            if failed:
                break  # a frame's own error (no answer in time, a lost bus): no more frames; raised at rest below
            if len(pending) < IN_FLIGHT:
                task = asyncio.create_task(one_frame(time.time()))
                pending.add(task)
                task.add_done_callback(settled)
            next_t += interval_s
            delay = next_t - loop.time()
            if delay < 0:  # fell behind (a loaded machine): keep the interval, skip the ticks missed
                next_t += math.ceil(-delay / interval_s) * interval_s
                delay = next_t - loop.time()
            await asyncio.wait({motion}, timeout=delay)
        # The line was planned whole and runs to its end (a stop is the interrupter's, on Ctrl-C): any error is
        # raised with the arm at rest, so a retract never queues behind a motion still under way.
        result = await motion
        if pending:
            await asyncio.gather(*pending, return_exceptions=True)
        if failed:
            raise failed[0]
        return result
    finally:
        for task in pending:
            task.cancel()
        if not motion.done():
            motion.cancel()
        await asyncio.gather(motion, *pending, return_exceptions=True)


def _sweep_frame(run: SweepRun, index: int, attrs: dict[str, Any], t_send: float, t_recv: float) -> SweepFrame | None:
    """The frame of a vision node's answer, not yet placed; None for a refusal (counted in ``run``)."""
    if attrs.get("error") or "sharpness" not in attrs or "frame_t" not in attrs:
        run.errors += 1
        run.first_error = run.first_error or str(attrs.get("error") or "no sharpness in the answer")
        log.debug("sweep frame refused: %s", attrs.get("error"))
        return None
    return SweepFrame(index, math.nan, float(attrs["sharpness"]), t_send_s=t_send, t_recv_s=t_recv,
                      frame_t_s=float(attrs["frame_t"]), exposure_s=float(attrs.get("exposure_ms", 0.0)) / 1e3,
                      readout_s=float(attrs.get("readout_ms", 0.0)) / 1e3)


def _peak_known(run: SweepRun, frames: list[SweepFrame], feed: StateFeed, params: Any) -> bool:
    """Online, the robot still moving: place the frames the state stream covers so far and tell whether their
    fit already settles the peak."""
    _place_vision_clock(run, frames)
    for g in frames:
        if math.isnan(g.offset_mm) and feed.track.covers(g.t_mid_s):
            g.offset_mm = feed.track.at(g.t_mid_s)
    placed = [g for g in [*run.frames, *frames] if math.isfinite(g.offset_mm)]
    fit = fit_peak([g.offset_mm for g in placed], [g.sharpness for g in placed])
    return fit.ok and fit.bracketed and fit.sigma_mm <= params.max_peak_sigma_mm


def _here() -> Any:
    from aioadept.commands import Here

    return Here()


def _place_vision_clock(run: SweepRun, frames: list[SweepFrame]) -> None:
    """Bound the vision node's clock offset by every frame so far (the exposure starts after its request was sent,
    and the frame is read out before its answer arrives) and set each frame's mid-exposure in local time."""
    lo, hi = run.vision_offset_bounds_s
    for f in frames:
        hi = min(hi, f.frame_t_s - f.t_send_s)
        lo = max(lo, f.frame_t_s + f.exposure_s + f.readout_s - f.t_recv_s)
    run.vision_offset_bounds_s = (lo, hi)
    run.vision_offset_s = clock_offset(lo, hi)
    for f in frames:
        f.t_mid_s = f.frame_t_s + f.exposure_s / 2.0 - run.vision_offset_s


def _place_by_profile(run: SweepRun, frames: list[SweepFrame], result: Any, plan: SweepPlan, ramp_s: float,
                      epoch_minus_loop: float) -> None:
    """Without a state stream: the planned trapezoid between the motion's start and its end, both from the acks.
    The server clock is mapped to the local one by the bounds every ack gives (sent before it started, received
    after it was done), the value nearest their middle."""
    msgs = list(result.messages)
    lo, hi = -math.inf, math.inf
    for m in msgs:
        send, recv = m.t_send_s + epoch_minus_loop, m.t_recv_s + epoch_minus_loop
        hi = min(hi, m.ack.t_start_s - send)
        lo = max(lo, m.ack.t_done_s - recv)
    off = (lo + hi) / 2.0
    # How far off the placement may be in time: half the bounds' width and half the server clock's 1 ms tick.
    run.timing_sigma_mm = max(run.timing_sigma_mm, plan.speed_mm_s * ((hi - lo) / 2.0 + 0.0005))
    move = next(m for m in msgs if m.skill == "move_to_s")
    brk = msgs[-1]
    t0 = move.ack.t_done_s - off  # a motion skill returns as its motion starts (V+ forward processing)
    t1 = brk.ack.t_done_s - off   # break returns when the robot is at rest
    planned = abs(plan.to_mm - plan.from_mm) / plan.speed_mm_s + ramp_s  # real time (ramp_s: the scaled ramp)
    # The measured duration against the planned one: a robot slower or faster than planned stretches the profile
    # as a whole.
    ramp = ramp_s * (t1 - t0) / planned if planned > 0 else ramp_s
    for f in frames:
        f.offset_mm = profile_offset(f.t_mid_s, t0, t1, plan.from_mm, plan.to_mm, ramp)


__all__ = ["MODES", "SWEEP_RANGES", "sweep_focus"]
