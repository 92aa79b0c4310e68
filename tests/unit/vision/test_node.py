"""The processing node's request -> attributes logic (no sockets), and the vision command's options."""

from __future__ import annotations

import numpy as np
import pytest

from aioadept.geometry import Pose
from aioadept.vision.__main__ import make_sources, resolve_options
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
        node = VisionNode(acq)
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
    assert resolve_options([]).source == ["virtual"] and resolve_options([]).policy == "nearest"
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
