"""``aioadept vision`` as a real subprocess answering VisionRequests over real ZeroMQ on 127.0.0.1."""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sys
import time

import cv2
import numpy as np
import pytest

from aioadept.testing.nodes import running_node
from aioadept.bus.communicator import Communicator
from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import Publisher
from aioadept.geometry import Pose
from aioadept.vision.virtual_camera import paper_approach_pose

APPROACH = paper_approach_pose()


@contextlib.asynccontextmanager
async def vision_process(tmp_path, *args: str):
    """Start ``aioadept vision`` on free ports; yield (process, READY fields); stopped on exit."""
    async with running_node("vision", "--request-endpoint", "tcp://127.0.0.1:0", "--response-endpoint",
                            "tcp://127.0.0.1:0", *args, log_path=tmp_path / "vision.log",
                            expect_clean_exit=False) as node:
        yield node.proc, node.ready


async def publish_states(pub: Publisher, pose_ref: list[Pose], stop: asyncio.Event) -> None:
    """A 100 Hz robot state stream of whatever pose ``pose_ref[0]`` holds (what the sim publishes)."""
    t0 = time.time()
    while not stop.is_set():
        state = RobotState(t_s=time.time() - t0, wall_time_s=time.time(), joints_deg=(0,) * 6, pose=pose_ref[0])
        await pub.publish(ROBOT_STATE_TOPIC, state.to_bytes())
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(0.01):  # the stream's period, and a prompt stop
                await stop.wait()


async def request_until_object(comm: Communicator) -> dict:
    """The node's SUB joins our state stream at its own pace: ask again (fresh id) until it sees the object."""
    while True:
        resp = await comm.request("VisionRequest", {}, timeout_s=5.0)
        if "error" not in resp.attributes:
            return dict(resp.attributes)
        assert resp.attributes["error"].startswith(("no object found", "stale robot state: no robot state received"))


@pytest.mark.timeout(40)
async def test_vision_process_follows_the_robot_state_and_measures_sharpness(tmp_path):
    pose_ref = [APPROACH @ Pose(z=20.0)]  # on the default focal plane
    stop = asyncio.Event()
    async with Publisher("tcp://127.0.0.1:0") as pub:
        feeder = asyncio.create_task(publish_states(pub, pose_ref, stop))
        try:
            async with vision_process(tmp_path, "--state-endpoint", pub.actual_endpoint, "--fps", "30",
                                      "--policy", "after", "--seed", "1") as (proc, ready):
                assert ready["cameras"] == "virtual" and ready["policy"] == "after" and ready["thread"] == "auto"
                async with Communicator(ready["request"], ready["response"], timeout_s=5.0) as comm:
                    async with asyncio.timeout(20):
                        focused = await request_until_object(comm)
                    pose_ref[0] = APPROACH  # 20 mm out of focus
                    with contextlib.suppress(TimeoutError):
                        async with asyncio.timeout(0.2):  # let the node receive ~20 states of the new pose
                            await stop.wait()
                    t_request = time.time()
                    resp = await comm.request("VisionRequest", {"t_request": t_request}, timeout_s=5.0)
                    blurred = dict(resp.attributes)
        finally:
            stop.set()
            await feeder
    assert "error" not in blurred, blurred
    assert focused["sharpness"] > 4 * blurred["sharpness"] > 0
    assert blurred["frame_t"] >= t_request  # policy "after"
    assert blurred["frame_t"] - t_request < 1.0 and blurred["frame_age_ms"] <= 0
    assert 0 < blurred["proc_time_ms"] < 200 and blurred["camera"] == "virtual"
    assert proc.returncode == 0  # SIGTERM: clean exit
    log = (tmp_path / "vision.log").read_text()
    assert "VisionRequest" in log and "sharpness=" in log


@pytest.mark.timeout(30)
async def test_vision_process_reports_no_object_and_stops_on_sigint(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(3):
        cv2.imwrite(str(folder / f"{i:03d}.png"), np.full((96, 128), 20, np.uint8))  # no calibration object
    saved = tmp_path / "saved"
    async with vision_process(tmp_path, "--source", f"folder:{folder}", "--fps", "50",
                              "--save-frames", str(saved)) as (proc, ready):
        assert ready["cameras"] == "folder"
        async with Communicator(ready["request"], ready["response"], timeout_s=5.0) as comm:
            resp = await comm.request("VisionRequest", {}, timeout_s=5.0)
        proc.send_signal(signal.SIGINT)
        async with asyncio.timeout(5):
            rc = await proc.wait()
    attrs = resp.attributes
    assert attrs["error"].startswith("no object found") and "sharpness" not in attrs
    assert attrs["camera"] == "folder" and attrs["frame_t"] > 0
    assert rc == 0
    assert (saved / "frames.csv").read_text().count("\n") == 2  # header + the one served frame


@pytest.mark.timeout(20)
async def test_vision_process_rejects_a_bad_source(tmp_path):
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "aioadept.vision", "--request-endpoint", "tcp://127.0.0.1:0",
        "--response-endpoint", "tcp://127.0.0.1:0", "--source", "webcam", stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE)
    out, err = await proc.communicate()
    assert proc.returncode == 2 and b"READY" not in out and b"bad --source" in err


@pytest.mark.timeout(30)
async def test_vision_process_inline_mode_answers_repeated_ids_from_the_cache(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    cv2.imwrite(str(folder / "0.png"), np.full((96, 128), 20, np.uint8))
    async with vision_process(tmp_path, "--source", f"folder:{folder}", "--graph", "noop", "--inline",
                              "--fps", "30") as (proc, ready):
        assert ready["thread"] == "loop" and ready["graph"] == "noop"
        async with Communicator(ready["request"], ready["response"], timeout_s=5.0) as comm:
            first = await comm.request("VisionRequest", {"t_request": time.time()})
            second = await comm.request("VisionRequest", {"t_request": time.time()})
    assert first.attributes["sharpness"] == 0.0 and second.attributes["sharpness"] == 0.0
    assert second.attributes["frame_t"] >= first.attributes["frame_t"]
    log = (tmp_path / "vision.log").read_text()
    assert log.count("VisionRequest") == 2  # each id processed (and logged) once, re-publications from the cache


@pytest.mark.timeout(30)
async def test_node_responder_answers_cheap_requests_at_once_and_waits_for_frames_on_the_loop(tmp_path):
    from aioadept.vision.acquisition import Acquisition
    from aioadept.vision.node import NodeResponder, VisionNode, noop_graph
    from aioadept.vision.sources import ImageFolderSource

    folder = tmp_path
    cv2.imwrite(str(folder / "0.png"), np.full((48, 64), 20, np.uint8))
    with Acquisition([ImageFolderSource(folder, loop=True)], fps=50) as acq:
        assert await asyncio.to_thread(acq.wait_ready, 5.0)
        for policy in ("nearest", "after"):
            # (a generous threshold: a no-op run preempted on a loaded machine must not look expensive)
            # (max_frame_age_s: the "ahead" request is 0.1 s younger than any frame nearest could pick)
            node = VisionNode(acq, noop_graph(), policy=policy, timeout_s=2.0, inline_max_ms=100.0,
                              max_frame_age_s=1.0)
            awaited = []  # requests that went through the Responder's worker task (VisionNode.handle)
            handle = node.handle

            async def counting_handle(*args, _handle=handle, _awaited=awaited):
                _awaited.append(args[1])
                return await _handle(*args)

            node.handle = counting_handle
            try:
                async with NodeResponder("tcp://127.0.0.1:0", "tcp://127.0.0.1:0", node) as responder:
                    async with Communicator(responder.peer_request_endpoint, responder.peer_response_endpoint,
                                            timeout_s=5.0) as comm:
                        answers = [await comm.request("VisionRequest", {"t_request": time.time()})
                                   for _ in range(4)]
                        # a request for a frame 0.1 s ahead: answered once that frame is grabbed
                        t_ahead = time.time() + 0.1
                        ahead = await comm.request("VisionRequest", {"t_request": t_ahead})
            finally:
                node.close()
            assert all(a.attributes["sharpness"] == 0.0 for a in answers)
            assert responder.handled == 5 and node.served == 5 and node.failed == 0, [a.attributes for a in answers] + [ahead.attributes]
            assert node.thread_runs == 1  # the first run (cost unknown) in the worker, the others on the loop
            assert node.inline_runs == 4
            if policy == "after":
                assert len(awaited) == 5  # every request may wait for its frame: all through the worker task
                assert ahead.attributes["frame_t"] >= t_ahead
                assert all(a.attributes["frame_age_ms"] <= 0 for a in answers)
            else:
                assert len(awaited) == 1  # only the first (cost unknown); the rest in the socket callback
                assert ahead.attributes["frame_t"] < t_ahead  # nearest: the newest frame at once
