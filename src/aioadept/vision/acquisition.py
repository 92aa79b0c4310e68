"""Acquisition into ring buffers, software-triggered or free-running, and the frame for a request (FxIS,
Semeniuta 2018). The ring, the two grabbing loops and their one stop share the same state.

**Software trigger** (``trigger="auto"`` for sources that can, ``"software"`` to insist): the source's thread waits
for :meth:`Acquisition.trigger`; a request triggers its own exposure and is answered from that frame, whatever the
policy, so it costs exposure + readout and never shows a pose from before the request. **Free-running**
(``trigger="free"``, and sources that cannot be triggered: video files, webcams, folders) works as below.

Where it sits: one :class:`Acquisition` owns one grabbing thread per source (:mod:`aioadept.vision.sources`); each
thread pushes timestamped frames into that source's :class:`FrameRing`. The processing node asks for the frame (or
the set of frames, one per camera) that belongs to a request time:

- policy ``"nearest"`` (the paper's; opt-in, the node bounds its age with ``max_frame_age_s``): the buffered frame whose timestamp is nearest ``t_request``, found by binary
  search; it answers at once. **Tie rule:** when two frames are equally far, the later one wins (the robot has
  stopped before the request is sent, so the later frame is the safer picture of the stopped robot);
- policy ``"after"`` (the default): the first frame whose exposure started at or after ``t_request``, waiting for it up to a timeout. Correct
  when the request is sent right after the robot stopped: no frame taken during the motion can be chosen, at the
  price of up to one frame period of latency.

Waiting comes in two forms: :meth:`Acquisition.frame_at` blocks the calling thread (on the ring's condition), and
:meth:`Acquisition.frame_at_async` awaits on the event loop without any thread: the wait registers a future with
the ring, and the grabbing thread that pushes a qualifying frame resolves it through
``loop.call_soon_threadsafe``. A ring with no waiter costs the grabbing threads nothing extra.

CPU is bounded: each thread grabs at most ``fps`` frames per second, sleeping (interruptibly) until the next frame
deadline; when a grab takes longer than the period the thread does not try to catch up in a burst.
"""

from __future__ import annotations

import asyncio
import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Literal

from aioadept.errors import VisionError
from aioadept.vision.sources import Camera, Frame

log = logging.getLogger(__name__)

Policy = Literal["nearest", "after"]
POLICIES: tuple[str, ...] = ("nearest", "after")
DEFAULT_POLICY: Policy = "after"
"""Never a frame whose exposure started before the request was sent (``nearest`` is opt-in, with a maximum age)."""
TriggerMode = Literal["auto", "software", "free"]
TRIGGER_MODES: tuple[str, ...] = ("auto", "software", "free")


class FrameRing:
    """A fixed-capacity ring buffer of frames in timestamp order, thread-safe.

    :meth:`push` overwrites the oldest frame when full. Frames must come with non-decreasing ``t_s``; a frame older
    than the newest (a replay that starts over) clears the ring first, so the order invariant always holds and the
    binary searches stay valid.
    """

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError("FrameRing capacity must be >= 1")
        self.capacity = capacity
        self._frames: list[Frame | None] = [None] * capacity
        self._times: list[float] = [0.0] * capacity
        self._start = 0   # physical index of the oldest frame
        self._count = 0
        self._cond = threading.Condition()
        # Event-loop waiters for "first frame at or after t": (t_s, loop, future), resolved by push().
        self._waiters: list[tuple[float, asyncio.AbstractEventLoop, asyncio.Future[Frame]]] = []
        self.pushed = 0
        # The newest failed triggered grab: (epoch s it started, error). A wait for a frame at or after a time no
        # later than that start was waiting for that grab, so it gets the error at once instead of a timeout.
        self._failure: tuple[float, VisionError] | None = None

    def __len__(self) -> int:
        return self._count

    def _phys(self, i: int) -> int:
        return (self._start + i) % self.capacity

    def push(self, frame: Frame) -> None:
        with self._cond:
            if self._count and frame.t_s < self._times[self._phys(self._count - 1)]:
                log.info("%s: timestamps went back (%.6f); ring cleared", frame.camera_id, frame.t_s)
                self._start = self._count = 0
            if self._count < self.capacity:
                j = self._phys(self._count)
                self._count += 1
            else:  # full: overwrite the oldest, which makes the next one the oldest
                j = self._start
                self._start = (self._start + 1) % self.capacity
            self._frames[j] = frame
            self._times[j] = frame.t_s
            self.pushed += 1
            self._cond.notify_all()
            if self._waiters:
                self._wake(frame)

    def _wake(self, frame: Frame) -> None:
        """Hand ``frame`` to every loop waiter it satisfies (called with the lock held, in the pushing thread)."""
        keep = []
        for waiter in self._waiters:
            t_s, loop, fut = waiter
            if frame.t_s < t_s:
                keep.append(waiter)
                continue
            try:
                loop.call_soon_threadsafe(_resolve, fut, frame)
            except RuntimeError:  # that loop is closed: nobody is waiting any more
                pass
        self._waiters = keep

    def fail(self, t_started: float, exc: VisionError) -> None:
        """A software-triggered grab that started at ``t_started`` failed: every wait for a frame at or after a
        time up to ``t_started`` (it was waiting for that grab) raises ``exc`` now; later waits are unaffected."""
        with self._cond:
            self._failure = (t_started, exc)
            self._cond.notify_all()
            keep = []
            for waiter in self._waiters:
                t_s, loop, fut = waiter
                if t_s > t_started:
                    keep.append(waiter)
                    continue
                try:
                    loop.call_soon_threadsafe(_reject, fut, exc)
                except RuntimeError:
                    pass
            self._waiters = keep

    def _failed_for(self, t_s: float) -> VisionError | None:
        f = self._failure
        return f[1] if f is not None and t_s <= f[0] else None

    def frames(self) -> list[Frame]:
        """All buffered frames, oldest first."""
        with self._cond:
            return [self._frames[self._phys(i)] for i in range(self._count)]  # type: ignore[misc]

    def latest(self) -> Frame | None:
        with self._cond:
            return self._frames[self._phys(self._count - 1)] if self._count else None

    def _bisect_left(self, t_s: float) -> int:
        """Logical index of the first frame with ``t >= t_s`` (``count`` if none); binary search over the ring."""
        lo, hi = 0, self._count
        while lo < hi:
            mid = (lo + hi) // 2
            if self._times[self._phys(mid)] < t_s:
                lo = mid + 1
            else:
                hi = mid
        return lo

    def _bisect_right(self, t_s: float) -> int:
        """Logical index of the first frame with ``t > t_s`` (``count`` if none)."""
        lo, hi = 0, self._count
        while lo < hi:
            mid = (lo + hi) // 2
            if self._times[self._phys(mid)] <= t_s:
                lo = mid + 1
            else:
                hi = mid
        return lo

    def nearest(self, t_s: float) -> Frame | None:
        """The frame whose timestamp is nearest ``t_s``. On a tie the later frame: of two frames equally far before
        and after, the one after; of frames with equal timestamps, the last pushed. None when empty."""
        with self._cond:
            if not self._count:
                return None
            i = self._bisect_left(t_s)  # frames [0, i) are before t_s, [i, count) at or after it
            if i > 0 and (i == self._count or
                          t_s - self._times[self._phys(i - 1)] < self._times[self._phys(i)] - t_s):
                return self._frames[self._phys(i - 1)]  # strictly nearer before; the last frame before t_s
            # At or after (strictly nearer, or a tie): the last of the frames sharing that timestamp.
            j = self._bisect_right(self._times[self._phys(i)]) - 1
            return self._frames[self._phys(j)]

    def first_at_or_after(self, t_s: float) -> Frame | None:
        """The oldest frame with ``t >= t_s``, or None when no such frame is buffered."""
        with self._cond:
            i = self._bisect_left(t_s)
            return self._frames[self._phys(i)] if i < self._count else None

    def wait_at_or_after(self, t_s: float, timeout_s: float) -> Frame | None:
        """Like :meth:`first_at_or_after`, waiting up to ``timeout_s`` for such a frame to be pushed."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while True:
                i = self._bisect_left(t_s)
                if i < self._count:
                    return self._frames[self._phys(i)]
                if (exc := self._failed_for(t_s)) is not None:
                    raise exc
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._cond.wait(remaining)

    async def await_at_or_after(self, t_s: float, timeout_s: float) -> Frame | None:
        """Like :meth:`wait_at_or_after`, awaited on the running loop without blocking it or using a thread.

        Returns as soon as the grabbing thread has pushed such a frame (one ``call_soon_threadsafe`` hop), or None
        after ``timeout_s``. Cancellation is safe: the waiter is removed either way.
        """
        loop = asyncio.get_running_loop()
        with self._cond:
            i = self._bisect_left(t_s)
            if i < self._count:
                return self._frames[self._phys(i)]
            if (exc := self._failed_for(t_s)) is not None:
                raise exc
            if timeout_s <= 0:
                return None
            fut: asyncio.Future[Frame] = loop.create_future()
            waiter = (t_s, loop, fut)
            self._waiters.append(waiter)  # under the lock: a push cannot slip between the check and this
        try:
            async with asyncio.timeout(timeout_s):
                return await fut
        except TimeoutError:
            return None
        finally:
            with self._cond:
                if waiter in self._waiters:
                    self._waiters.remove(waiter)


def _resolve(fut: asyncio.Future[Frame], frame: Frame) -> None:
    if not fut.done():  # not timed out or cancelled meanwhile
        fut.set_result(frame)


def _reject(fut: asyncio.Future[Frame], exc: BaseException) -> None:
    if not fut.done():
        fut.set_exception(exc)


@dataclass(frozen=True, slots=True)
class SourceStats:
    """Counters of one grabbing thread."""

    camera_id: str
    grabbed: int
    errors: int
    exhausted: bool
    running: bool


class Acquisition:
    """Grabs continuously from ``sources`` (one owned thread each) into ring buffers of ``buffer_size`` frames.

    ``fps`` caps each source's grab rate (None: as fast as ``grab()`` returns, for sources that block on real
    hardware). ``on_frame(frame)`` is called in the grabbing thread after each push (e.g. a recorder); it must be
    quick, and its exceptions are logged. Use as a context manager, or :meth:`start` / :meth:`stop`; ``stop``
    joins every thread and closes the sources.
    """

    def __init__(self, sources: Sequence[Camera], *, buffer_size: int = 64, fps: float | None = 15.0,
                 on_frame: Callable[[Frame], None] | None = None, close_sources: bool = True,
                 trigger: TriggerMode = "free") -> None:
        if trigger not in TRIGGER_MODES:
            raise ValueError(f"trigger must be one of {TRIGGER_MODES}, got {trigger!r}")
        bad = [s.camera_id for s in sources if trigger == "software" and not getattr(s, "can_trigger", False)]
        if bad:
            raise ValueError(f"sources {bad} cannot be software-triggered; use trigger='auto' or 'free'")
        if not sources:
            raise ValueError("Acquisition needs at least one source")
        ids = [s.camera_id for s in sources]
        if len(set(ids)) != len(ids):
            raise ValueError(f"camera ids must be unique, got {ids}")
        if fps is not None and fps <= 0:
            raise ValueError("fps must be > 0")
        self.sources = tuple(sources)
        self.buffer_size = buffer_size
        self.fps = fps
        self._on_frame = on_frame
        self._close_sources = close_sources
        self.rings: dict[str, FrameRing] = {s.camera_id: FrameRing(buffer_size) for s in sources}
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._errors = {cid: 0 for cid in ids}
        self._exhausted = {cid: False for cid in ids}
        self.triggered: dict[str, bool] = {
            s.camera_id: trigger != "free" and bool(getattr(s, "can_trigger", False)) for s in sources}
        """Per camera: software-triggered (a frame per :meth:`trigger`) rather than free-running."""
        self._trigger_events = {cid: threading.Event() for cid in ids}
        self._trigger_t: dict[str, float | None] = {cid: None for cid in ids}
        self._trigger_lock = threading.Lock()

    @property
    def camera_ids(self) -> tuple[str, ...]:
        return tuple(self.rings)

    # ------------------------------------------------------------------------------------------- threads
    def start(self) -> Acquisition:
        if self._threads:
            raise RuntimeError("Acquisition already started")
        for src in self.sources:
            loop = self._trigger_loop if self.triggered[src.camera_id] else self._grab_loop
            t = threading.Thread(target=loop, args=(src,), name=f"grab:{src.camera_id}",
                                 daemon=src.stop_wait_s is not None)
            t.start()
            self._threads.append(t)
            if self.triggered[src.camera_id]:
                self.trigger(src.camera_id)  # a first frame, so wait_ready() and the one-off costs are done
        return self

    def trigger(self, camera_id: str | None = None) -> float:
        """Software-trigger ``camera_id`` (default: the first camera): its grabbing thread starts an exposure as soon
        as it is free. Returns the trigger's epoch time; the frame it takes has ``t_s`` (exposure start) at or
        after it. Triggers that arrive while one is still pending share its frame."""
        cid = camera_id if camera_id is not None else self.camera_ids[0]
        if not self.triggered.get(cid, False):
            raise VisionError(f"camera {cid!r} is not software-triggered")
        with self._trigger_lock:
            t = time.time()
            if self._trigger_t[cid] is None:
                self._trigger_t[cid] = t
            self._trigger_events[cid].set()
        return t

    def _trigger_loop(self, src: Camera) -> None:
        cid = src.camera_id
        ring, event = self.rings[cid], self._trigger_events[cid]
        while True:
            event.wait()
            if self._stop.is_set():
                return
            with self._trigger_lock:
                event.clear()
                t_trigger, self._trigger_t[cid] = self._trigger_t[cid], None
            t_started = time.time()
            try:
                frame = src.grab()
            except Exception as exc:
                self._errors[cid] += 1
                if isinstance(exc, VisionError):  # a camera's own words (timeout, lost frame, camera gone)
                    log.warning("%s: triggered grab failed: %s", cid, exc)
                    err = exc
                else:
                    log.exception("%s: triggered grab failed", cid)
                    err = VisionError(f"{cid}: grab failed: {type(exc).__name__}: {exc}")
                # The requests waiting for this exposure get the error now, not after their timeout.
                ring.fail(t_started, err)
                continue
            if frame is None:
                self._exhausted[cid] = True
                log.info("%s: source exhausted after %d frames", cid, ring.pushed)
                return
            ring.push(replace(frame, t_trigger=t_trigger))
            if self._on_frame is not None:
                try:
                    self._on_frame(frame)
                except Exception:
                    log.exception("%s: on_frame callback failed", cid)

    def _grab_loop(self, src: Camera) -> None:
        ring = self.rings[src.camera_id]
        period = 1.0 / self.fps if self.fps else 0.0
        deadline = time.monotonic()
        while not self._stop.is_set():
            try:
                frame = src.grab()
            except Exception as exc:  # a camera's own words (VisionError: lost, timeout) in one line; a bug in full
                self._errors[src.camera_id] += 1
                log.warning("%s: grab failed: %s", src.camera_id, exc, exc_info=not isinstance(exc, VisionError))
                self._stop.wait(max(period, 0.05))  # do not spin on a broken device
                continue
            if frame is None:
                self._exhausted[src.camera_id] = True
                log.info("%s: source exhausted after %d frames", src.camera_id, ring.pushed)
                return
            ring.push(frame)
            if self._on_frame is not None:
                try:
                    self._on_frame(frame)
                except Exception:
                    log.exception("%s: on_frame callback failed", src.camera_id)
            if period:
                deadline += period
                now = time.monotonic()
                if deadline > now:
                    self._stop.wait(deadline - now)  # pacing (bounded CPU), woken at once by stop()
                else:
                    deadline = now  # behind: skip the missed slots instead of bursting

    def stop(self) -> None:
        """Stop and join every grabbing thread, then close the sources (idempotent).

        A thread notices the stop between grabs, so stopping takes at most one ``grab()``; a device whose read
        never returns keeps ``stop()`` waiting (closing an OpenCV capture under a reading thread is not safe) unless
        its ``Camera.stop_wait_s`` bounds the wait (GigE): then it goes on without it, and says so."""
        self._stop.set()
        for ev in self._trigger_events.values():
            ev.set()  # wakes the triggered threads, which then see the stop
        # no threads before a start or after an earlier stop (stop is idempotent)
        for t, src in zip(self._threads, self.sources, strict=False):
            t.join(t_s := src.stop_wait_s)
            if t.is_alive():
                log.warning("%s: a grab is still running after %g s: stopped without it", src.camera_id, t_s)
        self._threads.clear()
        if self._close_sources:
            for s in self.sources:
                try:
                    s.close()
                except Exception:
                    log.exception("%s: close failed", s.camera_id)

    def __enter__(self) -> Acquisition:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def wait_ready(self, timeout_s: float) -> bool:
        """Wait until every source has buffered a frame (a node announces READY only then); False on timeout."""
        deadline = time.monotonic() + timeout_s
        for ring in self.rings.values():
            try:
                if ring.wait_at_or_after(-math.inf, max(0.0, deadline - time.monotonic())) is None:
                    return False
            except VisionError:  # the first triggered grab failed
                return False
        return True

    def stats(self) -> list[SourceStats]:
        alive = {t.name for t in self._threads if t.is_alive()}
        return [SourceStats(cid, self.rings[cid].pushed, self._errors[cid], self._exhausted[cid],
                            f"grab:{cid}" in alive) for cid in self.rings]

    # ------------------------------------------------------------------------------------------- lookup
    def _ring(self, camera_id: str | None) -> FrameRing:
        if camera_id is None:
            return next(iter(self.rings.values()))
        try:
            return self.rings[camera_id]
        except KeyError:
            raise VisionError(f"unknown camera {camera_id!r}; have {list(self.rings)}") from None

    def frame_at(self, t_s: float, *, camera_id: str | None = None, policy: Policy = DEFAULT_POLICY,
                 timeout_s: float = 1.0) -> Frame:
        """The frame of ``camera_id`` (default: the first source) for request time ``t_s`` under ``policy``.

        Raises :class:`VisionError` when there is none: no frame yet (``nearest``), or none at/after ``t_s``
        within ``timeout_s`` (``after``), or an unknown camera or policy.
        """
        ring = self._ring(camera_id)
        cid = camera_id or self.camera_ids[0]
        if self.triggered.get(cid, False):
            # Whatever the policy: this request takes its own exposure, which starts after the trigger.
            t_trigger = self.trigger(cid)
            frame = ring.wait_at_or_after(t_trigger, timeout_s)
            if frame is None:
                raise VisionError(f"no frame from {cid} within {timeout_s:.3f} s of its software trigger")
            return frame
        if policy == "nearest":
            frame = ring.nearest(t_s)
            if frame is None:
                raise VisionError(f"no frame from {camera_id or self.camera_ids[0]} yet")
            return frame
        if policy == "after":
            frame = ring.wait_at_or_after(t_s, timeout_s)
            if frame is None:
                raise VisionError(f"no frame at or after t={t_s:.3f} from {camera_id or self.camera_ids[0]} "
                                  f"within {timeout_s:.3f} s")
            return frame
        raise VisionError(f"unknown policy {policy!r}; use one of {POLICIES}")

    async def frame_at_async(self, t_s: float, *, camera_id: str | None = None, policy: Policy = DEFAULT_POLICY,
                             timeout_s: float = 1.0) -> Frame:
        """:meth:`frame_at` for the event loop: ``nearest`` answers at once, ``after`` awaits the grabbing thread's
        push of the first frame at or after ``t_s`` (no thread is blocked, the loop keeps running). Same errors."""
        cid = camera_id or self.camera_ids[0]
        if self.triggered.get(cid, False):
            ring = self._ring(cid)
            t_trigger = self.trigger(cid)
            frame = await ring.await_at_or_after(t_trigger, timeout_s)
            if frame is None:
                raise VisionError(f"no frame from {cid} within {timeout_s:.3f} s of its software trigger")
            return frame
        if policy != "after":
            return self.frame_at(t_s, camera_id=camera_id, policy=policy)
        frame = await self._ring(camera_id).await_at_or_after(t_s, timeout_s)
        if frame is None:
            raise VisionError(f"no frame at or after t={t_s:.3f} from {camera_id or self.camera_ids[0]} "
                              f"within {timeout_s:.3f} s")
        return frame

    def frame_set(self, t_s: float, *, policy: Policy = DEFAULT_POLICY, timeout_s: float = 1.0,
                  camera_ids: Sequence[str] | None = None) -> dict[str, Frame]:
        """One frame per camera for the same request time (FxIS frame sets), keyed by camera id.

        With ``after`` the timeout is shared: the whole set waits at most ``timeout_s``.
        """
        deadline = time.monotonic() + timeout_s
        out: dict[str, Frame] = {}
        for cid in camera_ids or self.camera_ids:
            out[cid] = self.frame_at(t_s, camera_id=cid, policy=policy,
                                     timeout_s=max(0.0, deadline - time.monotonic()))
        return out
