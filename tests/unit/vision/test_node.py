"""The processing node's request -> attributes logic (no sockets), and the vision command's options."""

from __future__ import annotations

import asyncio
import inspect
import threading
import time

import numpy as np
import pytest

from aioadept.geometry import Pose
from aioadept.vision.service import make_sources
from aioadept.cli.vision import resolve_options
from aioadept.vision.acquisition import Acquisition
from aioadept.vision.node import VisionNode, noop_graph
from aioadept.vision.sources import Camera, Frame
from aioadept.vision.virtual_camera import paper_approach_pose, paper_camera

APPROACH = paper_approach_pose()


class Replay(Camera):
    """A real camera over fixed frames with given timestamps (then exhausted)."""

    def __init__(self, camera_id: str, frames: list[tuple[float, np.ndarray]]) -> None:
        self.camera_id = camera_id
        self._frames = list(frames)
        self._i = 0

    def grab(self) -> Frame | None:
        if self._i >= len(self._frames):
            return None
        t, img = self._frames[self._i]
        self._i += 1
        return Frame(img, t, self.camera_id, self._i - 1)


def _loaded(acq: Acquisition, last_t: dict[str, float]) -> None:
    """Wait (on the rings' condition) until each camera's last replayed frame is buffered."""
    for cid, t in last_t.items():
        assert acq.rings[cid].wait_at_or_after(t, timeout_s=5.0) is not None


@pytest.mark.timeout(20)
def test_node_answers_from_the_nearest_frame_of_each_camera():
    cam = paper_camera(seed=2, noise_sigma=1.0)
    sharp, blurred = cam.render(APPROACH @ Pose(z=20)), cam.render(APPROACH)
    blank = np.full_like(sharp, 18)
    a = Replay("a", [(10.0, blurred), (11.0, sharp), (12.0, blurred)])
    b = Replay("b", [(10.0, blank), (11.2, sharp)])
    with Acquisition([a, b], fps=None) as acq:
        _loaded(acq, {"a": 12.0, "b": 11.2})
        node = VisionNode(acq, policy="nearest", max_frame_age_s=float("inf"))
        try:
            out = node.process("VisionRequest", "id1", {"t_request": 11.1})
            only_b = node.process("VisionRequest", "id2", {"t_request": 10.2, "camera": "b"})
        finally:
            node.close()
    assert out["camera"] == "a" and out["frame_t"] == 11.0 and out["frame_seq"] == 1
    assert out["frame_age_ms"] == pytest.approx(100.0)
    assert out["sharpness"] > 100 and out["proc_time_ms"] > 0
    assert out["frame_t.b"] == 11.2 and out["sharpness.b"] == pytest.approx(out["sharpness"], rel=0.1)
    assert only_b["camera"] == "b" and only_b["error"].startswith("no object found") and "sharpness" not in only_b
    assert node.served == 2 and node.failed == 1


@pytest.mark.timeout(20)
async def test_node_handler_runs_in_its_worker_thread_and_reports_missing_frames():
    with Acquisition([Replay("a", [(5.0, np.zeros((8, 8), np.uint8))])], fps=None) as acq:
        _loaded(acq, {"a": 5.0})
        node = VisionNode(acq, noop_graph(), policy="after", timeout_s=0.05)
        try:
            late = await node.handle("VisionRequest", "x", {"t_request": 6.0})
            ok = await node.handle("VisionRequest", "y", {"t_request": 4.0})
            assert node._executor is not None
            inline = node.handle_inline("VisionRequest", "z", {"t_request": 4.0})
        finally:
            node.close()
    assert node._executor is None
    assert "no frame at or after" in late["error"] and late["camera"] == "a"
    assert ok["sharpness"] == 0.0 and ok["frame_t"] == 5.0
    same = {k: v for k, v in ok.items() if k != "proc_time_ms"}
    assert {k: v for k, v in inline.items() if k != "proc_time_ms"} == same
    assert node.served == 3 and node.failed == 1


def test_options_from_config_file_and_command_line(tmp_path):
    cfg = tmp_path / "vision.toml"
    cfg.write_text('[vision]\nfps = 5\npolicy = "after"\nsource = "folder:/data"\nfocus-offset-mm = 12.5\n')
    opts = resolve_options(["--config", str(cfg), "--fps", "7"])
    assert opts.fps == 7.0 and opts.policy == "after" and opts.source == ["folder:/data"]
    assert opts.focus_offset_mm == 12.5 and opts.buffer_size == 64
    # No stale frames by default: 'after' (the demo's cell says the same), software trigger where possible.
    assert resolve_options([]).source == ["virtual"] and resolve_options([]).policy == "after"
    assert (resolve_options([]).trigger, resolve_options([]).max_frame_age) == ("auto", 0.1)
    bad = tmp_path / "bad.toml"
    bad.write_text("frames_per_second = 3\n")
    with pytest.raises(SystemExit):
        resolve_options(["--config", str(bad)])


def test_sources_from_specs_get_unique_ids(tmp_path):
    opts = resolve_options(["--source", "virtual", "--source", "virtual", "--focus-offset-mm", "10"])
    cams = make_sources(opts, None)
    assert [c.camera_id for c in cams] == ["virtual", "virtual1"]
    assert cams[0].focus_distance_mm == pytest.approx(300 - 10)
    with pytest.raises(ValueError, match="bad --source"):
        make_sources(resolve_options(["--source", "folder"]), None)


class Trigger(Camera):
    """A camera that delivers a frame (stamped now) each time the test releases one: grab() blocks until then."""

    def __init__(self, camera_id: str = "t") -> None:
        self.camera_id = camera_id
        self._go = threading.Semaphore(0)
        self._seq = 0
        self.stopped = False

    def release(self) -> None:
        self._go.release()

    def grab(self) -> Frame | None:
        self._go.acquire()
        if self.stopped:
            return None
        self._seq += 1
        return Frame(np.zeros((8, 8), np.uint8), time.time(), self.camera_id, self._seq)

    def close(self) -> None:
        self.stopped = True
        self._go.release()


def _stop(acq: Acquisition, cam: Trigger) -> None:
    cam.stopped = True
    cam.release()  # unblock grab() so stop() can join the thread
    acq.stop()


@pytest.mark.timeout(20)
async def test_after_policy_is_answered_as_soon_as_the_frame_is_grabbed_without_blocking_the_loop():
    cam = Trigger()
    acq = Acquisition([cam], fps=None).start()
    node = VisionNode(acq, noop_graph(), policy="after", timeout_s=5.0)
    loop = asyncio.get_running_loop()
    try:
        cam.release()
        assert acq.wait_ready(5.0)
        t_request = time.time()
        task = asyncio.create_task(node.handle("VisionRequest", "a", {"t_request": t_request}))
        for _ in range(5):  # the loop runs freely while the node waits for the frame
            await asyncio.sleep(0.01)
        assert not task.done() and node.thread_runs == 0
        released_at = loop.time()
        cam.release()
        out = await task
        answered_in = loop.time() - released_at
    finally:
        node.close()
        _stop(acq, cam)
    assert out["frame_t"] >= t_request and out["frame_seq"] == 2 and out["sharpness"] == 0.0
    assert answered_in < 1.0  # woken by the grab (typically < 1 ms), far before the 5 s timeout


@pytest.mark.timeout(20)
async def test_after_policy_timeout_gives_the_error_result():
    cam = Trigger()
    acq = Acquisition([cam], fps=None).start()
    node = VisionNode(acq, noop_graph(), policy="after", timeout_s=0.1)
    try:
        cam.release()
        assert acq.wait_ready(5.0)
        t0 = time.monotonic()
        out = await node.handle("VisionRequest", "a", {"t_request": time.time() + 60})
        waited = time.monotonic() - t0
    finally:
        node.close()
        _stop(acq, cam)
    assert out["error"].startswith("no frame at or after") and "within 0.100 s" in out["error"]
    assert out["camera"] == "t" and "sharpness" not in out
    assert 0.09 <= waited < 2.0 and node.failed == 1 and acq.rings["t"]._waiters == []


def _graph_recording_thread(seen: list[int], sleep_s: float = 0.0):
    from aioadept.vision.graph import CompGraph

    def f(image):
        seen.append(threading.get_ident())
        if sleep_s:
            time.sleep(sleep_s)
        return 1.0

    return CompGraph({"f": f}, {"f": ("image", "sharpness")}, name="rec")


@pytest.mark.timeout(20)
@pytest.mark.parametrize("mode", ["auto", "always", "never"])
async def test_graph_thread_policy_chooses_loop_or_worker(mode):
    seen: list[int] = []
    with Acquisition([Replay("a", [(5.0, np.zeros((8, 8), np.uint8))])], fps=None) as acq:
        _loaded(acq, {"a": 5.0})
        # A generous threshold: a trivial run preempted on a loaded machine must not look expensive.
        node = VisionNode(acq, _graph_recording_thread(seen), graph_thread=mode, inline_max_ms=100.0)
        try:
            for i in range(3):
                out = await node.handle("VisionRequest", str(i), {"t_request": 5.0})
                assert out["sharpness"] == 1.0
        finally:
            node.close()
    loop_thread = threading.get_ident()
    on_loop = [t == loop_thread for t in seen]
    expected = {"auto": [False, True, True],      # unknown cost: the worker; then cheap: the loop
                "always": [False, False, False], "never": [True, True, True]}[mode]
    assert on_loop == expected
    assert (node.inline_runs, node.thread_runs) == (sum(expected), 3 - sum(expected))
    assert node.cost_ms is not None and node.cost_ms < 100.0


@pytest.mark.timeout(20)
async def test_auto_keeps_an_expensive_graph_in_the_worker_and_comes_back_when_it_gets_cheap():
    seen: list[int] = []
    with Acquisition([Replay("a", [(5.0, np.zeros((8, 8), np.uint8))])], fps=None) as acq:
        _loaded(acq, {"a": 5.0})
        node = VisionNode(acq, _graph_recording_thread(seen, sleep_s=0.05), inline_max_ms=10.0)
        try:
            for i in range(3):
                await node.handle("VisionRequest", str(i), {"t_request": 5.0})
            assert node.thread_runs == 3 and node.inline_runs == 0 and node.cost_ms >= 45
            assert not node.runs_inline()
            node.graph = _graph_recording_thread(seen)  # now cheap: the average decays below the threshold
            for i in range(30):
                await node.handle("VisionRequest", f"c{i}", {"t_request": 5.0})
        finally:
            node.close()
    assert node.runs_inline() and node.inline_runs > 0
    assert seen[-1] == threading.get_ident()  # the last runs were on the loop thread
    with pytest.raises(ValueError, match="graph_thread"):
        VisionNode(acq, noop_graph(), graph_thread="sometimes")  # type: ignore[arg-type]


@pytest.mark.timeout(20)
async def test_respond_answers_at_once_only_when_nothing_needs_waiting():
    with Acquisition([Replay("a", [(5.0, np.zeros((8, 8), np.uint8))])], fps=None) as acq:
        _loaded(acq, {"a": 5.0})
        node = VisionNode(acq, noop_graph(), graph_thread="never", policy="nearest")
        after = VisionNode(acq, noop_graph(), graph_thread="never", policy="after", timeout_s=0.05)
        auto = VisionNode(acq, noop_graph(), inline_max_ms=100.0, policy="nearest")
        try:
            now = node.respond("VisionRequest", "a", {"t_request": 5.0})
            assert isinstance(now, dict) and now["sharpness"] == 0.0 and node.inline_runs == 1
            waits = after.respond("VisionRequest", "b", {"t_request": 5.0})
            assert inspect.isawaitable(waits) and (await waits)["frame_t"] == 5.0
            first = auto.respond("VisionRequest", "c", {"t_request": 5.0})  # cost unknown: the worker
            assert inspect.isawaitable(first) and (await first)["sharpness"] == 0.0
            assert isinstance(auto.respond("VisionRequest", "d", {"t_request": 5.0}), dict)  # now known cheap
        finally:
            for n in (node, after, auto):
                n.close()


def test_graph_thread_options():
    assert resolve_options([]).graph_thread == "auto" and resolve_options([]).graph_inline_max_ms == 5.0
    assert resolve_options(["--inline"]).graph_thread == "never"  # the old option, an alias
    opts = resolve_options(["--graph-thread", "always", "--graph-inline-max-ms", "2"])
    assert opts.graph_thread == "always" and opts.graph_inline_max_ms == 2.0
    for bad in (["--inline", "--graph-thread", "always"], ["--graph-thread", "maybe"],
                ["--graph-inline-max-ms", "-1"]):
        with pytest.raises(SystemExit):
            resolve_options(bad)


class AgedReplay(Replay):
    """Replay whose frames carry a robot-pose age, as the virtual camera's do."""

    def __init__(self, camera_id: str, frames: list[tuple[float, np.ndarray, float | None]]) -> None:
        super().__init__(camera_id, [(t, img) for t, img, _ in frames])
        self._ages = [age for _, _, age in frames]

    def grab(self) -> Frame | None:
        frame = super().grab()
        return None if frame is None else Frame(frame.image, frame.t_s, frame.camera_id, frame.seq,
                                                self._ages[frame.seq])


@pytest.mark.timeout(20)
def test_node_refuses_frames_whose_robot_pose_is_older_than_the_limit():
    sharp = paper_camera(seed=2, noise_sigma=1.0).render(APPROACH @ Pose(z=20))
    cam = AgedReplay("virtual", [(10.0, sharp, 0.0), (11.0, sharp, 0.5), (12.0, sharp, 0.51),
                                 (13.0, sharp, float("inf")), (14.0, sharp, 0.3)])
    with Acquisition([cam], fps=None) as acq:
        _loaded(acq, {"virtual": 14.0})
        node = VisionNode(acq)
        loose = VisionNode(acq, max_state_age_s=float("inf"))
        try:
            out = {t: node.process("VisionRequest", None, {"t_request": t}) for t in (10.0, 11.0, 12.0, 13.0)}
            async_out = asyncio.run(node.handle("VisionRequest", None, {"t_request": 12.0}))
            shorter = VisionNode(acq, max_state_age_s=0.2).process("VisionRequest", None, {"t_request": 14.0})
            unchecked = loose.process("VisionRequest", None, {"t_request": 13.0})
        finally:
            node.close()
            loose.close()
    assert node.max_state_age_s == 0.5
    assert out[10.0]["sharpness"] > 0 and out[11.0]["sharpness"] > 0  # at the limit: still answered
    for t, why in ((12.0, "robot state stream silent for 0.51 s"), (13.0, "no robot state received yet")):
        err = out[t]["error"]
        assert err.startswith("stale robot state: " + why) and "limit 0.5 s" in err, err
        assert "sharpness" not in out[t] and out[t]["frame_t"] == t
    assert async_out["error"].startswith("stale robot state") and "sharpness" not in async_out
    assert "limit 0.2 s" in shorter["error"]
    assert unchecked["sharpness"] > 0
    assert node.stale == 3 and node.failed == 3


@pytest.mark.parametrize("bad", [0, -1, float("nan"), True, "0.5"])
def test_node_max_state_age_must_be_positive(bad):
    with pytest.raises(ValueError, match="max_state_age_s"):
        VisionNode(Acquisition([Replay("a", [])]), max_state_age_s=bad)


@pytest.mark.timeout(20)
def test_node_answers_a_t_request_that_is_not_a_finite_number_with_an_error():
    blank = np.full((48, 64), 18, np.uint8)
    with Acquisition([Replay("a", [(10.0, blank)])], fps=None) as acq:
        _loaded(acq, {"a": 10.0})
        node = VisionNode(acq)
        try:
            outs = [node.process("VisionRequest", None, {"t_request": v}) for v in (float("nan"), float("inf"), "x")]
            async_out = asyncio.run(node.handle("VisionRequest", None, {"t_request": float("-inf")}))
        finally:
            node.close()
    for v, out in zip((float("nan"), float("inf"), "x"), outs, strict=True):
        assert out == {"error": f"bad request: t_request must be a finite number (epoch s), got {v!r}"}
    assert async_out["error"].startswith("bad request: t_request")


def test_vision_command_limit_options():
    opts = resolve_options([])
    assert (opts.max_state_age, opts.max_queue, opts.max_request_bytes) == (0.5, 32, 1 << 20)
    opts = resolve_options(["--max-state-age", "inf", "--max-queue", "4", "--max-request-bytes", "4096"])
    assert (opts.max_state_age, opts.max_queue, opts.max_request_bytes) == (float("inf"), 4, 4096)
    for bad in (["--max-state-age", "0"], ["--max-state-age", "nan"], ["--max-queue", "0"],
                ["--max-request-bytes", "-1"]):
        with pytest.raises(SystemExit) as info:
            resolve_options(bad)
        assert info.value.code == 2


def test_virtual_camera_frames_carry_the_age_of_the_robot_state():
    from aioadept.vision.virtual_camera import PoseHistory, RobotStateFollower

    clock = [100.0]
    follower = RobotStateFollower("tcp://127.0.0.1:1", history=PoseHistory(), clock=lambda: clock[0])
    assert follower.state_age_s() == float("inf")
    cam = paper_camera(None, noise_sigma=0.0, clock=lambda: clock[0], state_age=follower.state_age_s,
                       exposure_ms=0.0, sleep=None)
    assert cam.grab().pose_age_s == float("inf")
    follower.history.add(99.0, APPROACH)
    assert cam.grab().pose_age_s == pytest.approx(1.0) and follower.state_age_s(98.0) == 0.0
    assert paper_camera(None).grab().pose_age_s is None  # no follower: nothing to check


class _SlowRecorder:
    """A recorder whose write blocks until released: shows whether the answer waits for the frame to be saved."""

    def __init__(self) -> None:
        self.release = threading.Event()
        self.written: list[int] = []

    def write(self, frame: Frame) -> None:
        assert self.release.wait(10.0)
        self.written.append(frame.seq)


@pytest.mark.timeout(20)
def test_node_answers_before_the_frame_is_saved_and_close_saves_every_frame():
    img = np.full((48, 64), 18, np.uint8)
    recorder = _SlowRecorder()
    with Acquisition([Replay("a", [(10.0, img), (11.0, img)])], fps=None) as acq:
        _loaded(acq, {"a": 11.0})
        node = VisionNode(acq, noop_graph(), policy="nearest", recorder=recorder)  # type: ignore[arg-type]
        try:
            assert node.process("VisionRequest", "1", {"t_request": 10.0})["frame_seq"] == 0
            assert node.process("VisionRequest", "2", {"t_request": 11.0})["frame_seq"] == 1
            assert recorder.written == []  # answered while the writer thread is still blocked
            recorder.release.set()
        finally:
            node.close()
    assert recorder.written == [0, 1]
