"""Ring buffer lookups (nearest with wraparound and ties, at-or-after with waiting) and the grabbing threads."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.errors import VisionError
from aioadept.vision.acquisition import Acquisition, FrameRing
from aioadept.vision.sources import Camera, Frame

_IMG = np.zeros((2, 2), np.uint8)


def frame(t: float, seq: int = 0, cid: str = "c") -> Frame:
    return Frame(_IMG, t, cid, seq)


def ring_of(times, capacity) -> FrameRing:
    r = FrameRing(capacity)
    for i, t in enumerate(times):
        r.push(frame(t, i))
    return r


def test_nearest_with_wraparound():
    r = ring_of([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0], capacity=4)  # keeps 4..7, stored wrapped around
    assert [f.t_s for f in r.frames()] == [4.0, 5.0, 6.0, 7.0] and len(r) == 4
    assert r.nearest(0.0).t_s == 4.0          # before everything: the oldest
    assert r.nearest(5.4).t_s == 5.0
    assert r.nearest(5.6).t_s == 6.0
    assert r.nearest(6.9).t_s == 7.0
    assert r.nearest(100.0).t_s == 7.0        # after everything: the newest
    assert r.nearest(2.0).seq == 3            # overwritten frames are gone


def test_equal_distance_takes_the_later_frame():
    r = ring_of([1.0, 2.0, 3.0, 4.0, 5.0], capacity=3)   # 3, 4, 5 with the ring wrapped
    assert r.nearest(3.5).t_s == 4.0 and r.nearest(4.5).t_s == 5.0
    dup = ring_of([1.0, 2.0, 2.0, 3.0], capacity=8)      # equal timestamps: the later-pushed one at a tie
    assert dup.nearest(1.5).t_s == 2.0 and dup.nearest(1.5).seq == 2 and dup.nearest(2.0).seq == 2
    assert dup.first_at_or_after(2.0).seq == 1


def test_empty_ring():
    r = FrameRing(3)
    assert r.nearest(1.0) is None and r.first_at_or_after(0) is None and r.latest() is None
    with pytest.raises(ValueError):
        FrameRing(0)


def test_time_going_back_clears_the_ring():
    r = ring_of([1.0, 2.0, 3.0], capacity=5)
    r.push(frame(0.5, 9))
    assert [f.seq for f in r.frames()] == [9]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 40), min_size=1, max_size=30).map(sorted), st.integers(1, 12), st.integers(-5, 45))
def test_nearest_agrees_with_brute_force(times, capacity, query):
    # Integer times make ties frequent; halve them so queries fall between frames too.
    r = ring_of([t / 2 for t in times], capacity)
    q = query / 4
    kept = r.frames()
    best = min(abs(f.t_s - q) for f in kept)
    expected = max((f for f in kept if abs(f.t_s - q) == best), key=lambda f: f.seq)  # tie: the later
    assert r.nearest(q).seq == expected.seq
    after = [f for f in kept if f.t_s >= q]
    assert (r.first_at_or_after(q).seq if after else None) == (after[0].seq if after else None)


def test_wait_at_or_after_returns_when_the_frame_arrives():
    r = ring_of([1.0], capacity=4)
    pusher = threading.Timer(0.05, r.push, args=(frame(2.0, 1),))
    pusher.start()
    try:
        t0 = time.monotonic()
        f = r.wait_at_or_after(1.5, timeout_s=5.0)
        assert f.seq == 1 and time.monotonic() - t0 < 2.0
        assert r.wait_at_or_after(3.0, timeout_s=0.05) is None
    finally:
        pusher.join()


class CountingCamera(Camera):
    """A real Camera: frames stamped by a clock, optionally a limited number, optionally failing once."""

    def __init__(self, camera_id: str, *, limit: int | None = None, fail_at: int | None = None) -> None:
        self.camera_id = camera_id
        self.limit = limit
        self.fail_at = fail_at
        self.n = 0
        self.closed = False

    def grab(self) -> Frame | None:
        if self.limit is not None and self.n >= self.limit:
            return None
        self.n += 1
        if self.fail_at == self.n:
            raise OSError("cable unplugged")
        return Frame(_IMG, time.time(), self.camera_id, self.n)

    def close(self) -> None:
        self.closed = True


@pytest.mark.timeout(10)
def test_acquisition_paces_grabs_and_stops_its_threads():
    cam = CountingCamera("a")
    acq = Acquisition([cam], buffer_size=8, fps=50.0)
    with acq:
        assert acq.wait_ready(5.0)
        first = acq.rings["a"].wait_at_or_after(time.time() + 0.3, timeout_s=5.0)
        assert first is not None
    assert not any(t.is_alive() for t in threading.enumerate() if t.name == "grab:a")
    assert cam.closed
    # ~0.3 s at 50 fps is ~15 frames; a free-running loop would be thousands (a starved one on a loaded CI box
    # fewer, hence the loose lower bound).
    assert 3 <= cam.n <= 30
    assert len(acq.rings["a"]) == min(8, cam.n)


@pytest.mark.timeout(10)
def test_frame_sets_policies_errors_and_exhaustion():
    a, b, c = CountingCamera("a"), CountingCamera("b", fail_at=2), CountingCamera("c", limit=3)
    with Acquisition([a, b, c], buffer_size=16, fps=100.0) as acq:
        t_req = time.time()
        fs = acq.frame_set(t_req, policy="after", timeout_s=5.0, camera_ids=["a", "b"])
        assert set(fs) == {"a", "b"} and all(f.t_s >= t_req for f in fs.values())
        assert fs["a"].camera_id == "a" and fs["b"].camera_id == "b"
        near = acq.frame_at(t_req, camera_id="a")
        assert abs(near.t_s - t_req) <= abs(fs["a"].t_s - t_req)
        with pytest.raises(VisionError, match="within"):
            acq.frame_at(time.time() + 60, camera_id="c", policy="after", timeout_s=0.05)
        with pytest.raises(VisionError, match="unknown camera"):
            acq.frame_at(t_req, camera_id="zz")
        with pytest.raises(VisionError, match="unknown policy"):
            acq.frame_at(t_req, policy="first")  # type: ignore[arg-type]
        stats = {s.camera_id: s for s in acq.stats()}
    assert stats["b"].errors == 1 and stats["b"].grabbed >= 1
    assert stats["c"].exhausted and stats["c"].grabbed == 3


def test_acquisition_rejects_bad_options():
    with pytest.raises(ValueError):
        Acquisition([])
    with pytest.raises(ValueError, match="unique"):
        Acquisition([CountingCamera("a"), CountingCamera("a")])
    acq = Acquisition([CountingCamera("a")])
    with pytest.raises(VisionError, match="no frame"):
        acq.frame_at(1.0)
    assert not acq.wait_ready(0.01)  # not started: no frame comes


@pytest.mark.timeout(10)
async def test_async_wait_is_answered_as_soon_as_the_frame_is_pushed():
    import asyncio

    r = ring_of([1.0], capacity=4)
    loop = asyncio.get_running_loop()
    pushed_at: list[float] = []

    def push_later() -> None:  # a grabbing thread
        time.sleep(0.05)
        r.push(frame(1.2, 1))   # still before t: the waiter keeps waiting
        time.sleep(0.05)
        pushed_at.append(loop.time())
        r.push(frame(2.0, 2))

    ticks = 0

    async def ticker() -> None:  # the loop keeps running while the wait is pending
        nonlocal ticks
        while True:
            ticks += 1
            await asyncio.sleep(0.005)

    t = threading.Thread(target=push_later)
    tick_task = asyncio.create_task(ticker())
    t.start()
    try:
        f = await r.await_at_or_after(1.5, timeout_s=5.0)
        got_at = loop.time()
    finally:
        tick_task.cancel()
        t.join()
    assert f.seq == 2 and f.t_s == 2.0
    assert got_at - pushed_at[0] < 0.5     # woken by the push, not by a poll or the timeout
    assert ticks >= 5                        # ~0.1 s of waiting with a free loop
    assert r._waiters == []
    assert (await r.await_at_or_after(1.5, timeout_s=0)).seq == 2   # already there: no wait at all


@pytest.mark.timeout(10)
async def test_async_wait_times_out_with_the_error_and_forgets_the_waiter():
    cam = CountingCamera("c", limit=2)
    with Acquisition([cam], fps=None) as acq:
        assert acq.wait_ready(5.0)
        t0 = time.monotonic()
        with pytest.raises(VisionError, match="no frame at or after t=.* within 0.050 s"):
            await acq.frame_at_async(time.time() + 60, camera_id="c", policy="after", timeout_s=0.05)
        assert 0.04 <= time.monotonic() - t0 < 2.0
        assert acq.rings["c"]._waiters == []
        near = await acq.frame_at_async(time.time(), camera_id="c", policy="nearest")  # at once
        assert near.seq == 2
        with pytest.raises(VisionError, match="unknown camera"):
            await acq.frame_at_async(1.0, camera_id="zz", policy="after")
        with pytest.raises(VisionError, match="unknown policy"):
            await acq.frame_at_async(1.0, policy="first")  # type: ignore[arg-type]


@pytest.mark.timeout(10)
async def test_async_wait_on_a_live_camera_gets_the_first_frame_after_t():
    cam = CountingCamera("c")
    with Acquisition([cam], buffer_size=32, fps=100.0) as acq:
        assert acq.wait_ready(5.0)
        t_req = time.time()
        f = await acq.frame_at_async(t_req, camera_id="c", policy="after", timeout_s=5.0)
        after = [x for x in acq.rings["c"].frames() if x.t_s >= t_req]
    assert f.t_s >= t_req and f.seq == after[0].seq   # the first one, not a later one
