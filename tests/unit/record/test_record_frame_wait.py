"""A file-only recording logs the served frames at close, in the closing thread (not the nice-19 worker, which a loaded
machine starves), waiting for the node's low-priority writer; a node that saves nothing costs one wait."""

from __future__ import annotations

import os
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("rerun")
pytest.importorskip("cv2")

from aioadept.record import live  # noqa: E402
from aioadept.record.live import RunRecording  # noqa: E402
from aioadept.record.read import read_rrd  # noqa: E402
from aioadept.vision.sources import Frame, FrameRecorder  # noqa: E402

N = 6


def _responses(rec: RunRecording) -> None:
    t = time.time()
    for seq in range(N):
        attrs = {"camera": "virtual:0", "frame_seq": seq, "frame_t": t + seq * 0.1, "sharpness": 1.0 + seq}
        rec.on_response(SimpleNamespace(id=f"r{seq}", event_type="VisionResponse", attributes=attrs,
                                        t_recv_s=time.monotonic(), t_send_s=time.monotonic()))


def _slow_writer(folder, gap_s: float) -> threading.Thread:
    def write() -> None:
        fr = FrameRecorder(folder)
        for seq in range(N):
            time.sleep(gap_s)
            fr.write(Frame(image=np.full((48, 64), 40 * seq, np.uint8), t_s=time.time(), camera_id="virtual:0",
                           seq=seq))
        fr.close()

    th = threading.Thread(target=write, daemon=True)
    th.start()
    return th


@pytest.mark.timeout(60)
def test_a_node_that_saves_nothing_costs_one_wait(tmp_path, monkeypatch):
    monkeypatch.setattr(live, "FRAME_WAIT_S", 0.5)
    frames = tmp_path / "frames"
    frames.mkdir()
    rec = RunRecording(tmp_path / "run.rrd", frames_dir=frames).start()
    _responses(rec)
    t0 = time.monotonic()
    rec.close()
    assert rec.frames_missing == N
    assert time.monotonic() - t0 < 0.5 * N  # one wait, not one per frame
    assert "/camera/image" not in read_rrd(tmp_path / "run.rrd")


@pytest.mark.timeout(60)
def test_frames_are_logged_at_close_by_the_closing_thread_not_the_niced_worker(tmp_path):
    # The worker runs at nice 19 so as never to compete with a running focus loop; on a loaded machine that share of
    # a core made a dozen frames outlast close()'s join and get lost. After the run the frames are the closer's job.
    frames = tmp_path / "frames"
    writer = _slow_writer(frames, 0.0)
    writer.join(10)
    rec = RunRecording(tmp_path / "run.rrd", frames_dir=frames).start()
    niceness = []
    real_frame = rec._frame

    def spy(attrs, step):
        niceness.append(os.getpriority(os.PRIO_PROCESS, threading.get_native_id()))
        real_frame(attrs, step)

    rec._frame = spy
    _responses(rec)
    rec.close()
    assert niceness == [os.getpriority(os.PRIO_PROCESS, threading.get_native_id())] * N
    assert rec.frames_missing == 0
    assert len(read_rrd(tmp_path / "run.rrd")["/camera/image"]) == N
