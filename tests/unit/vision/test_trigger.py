"""Software-triggered acquisition and the no-stale-frame default: a request takes its own exposure, which starts
after the request was sent; ``nearest`` is opt-in and bounded by ``max_frame_age_s``; every answer says which
frame it used and when that frame was exposed."""

from __future__ import annotations

import time

import numpy as np
import pytest

from aioadept.vision.acquisition import Acquisition
from aioadept.vision.node import VisionNode, noop_graph
from aioadept.vision.sources import Camera, Frame
from aioadept.vision.virtual_camera import gige_readout_ms, paper_camera


class TriggerableCamera(Camera):
    """Takes a frame only when its thread asks, stamped with the exposure start; counts grabs."""

    can_trigger = True

    def __init__(self) -> None:
        self.camera_id = "t"
        self.grabs = 0

    def grab(self) -> Frame:
        t = time.time()
        self.grabs += 1
        return Frame(np.zeros((4, 4), np.uint8), t, self.camera_id, self.grabs - 1, None, 0.005, 0.0063)


def test_readout_of_a_1024x768_mono8_frame_over_gige():
    assert gige_readout_ms(1024 * 768) == pytest.approx(6.29, abs=0.01)
    cam = paper_camera(None)
    assert (cam.exposure_ms, round(cam.readout_ms, 2), cam.can_trigger) == (5.0, 6.29, True)


@pytest.mark.timeout(10)
async def test_each_request_triggers_its_own_exposure_after_it_was_sent():
    cam = TriggerableCamera()
    with Acquisition([cam], trigger="auto") as acq:
        assert acq.triggered == {"t": True} and acq.wait_ready(5.0)
        node = VisionNode(acq, noop_graph())  # default policy
        try:
            answers = []
            for _ in range(3):
                t_request = time.time()
                out = await node.handle("VisionRequest", "x", {"t_request": t_request})
                answers.append((t_request, out))
        finally:
            node.close()
    seqs = [out["frame_seq"] for _, out in answers]
    assert seqs == sorted(set(seqs)) and len(seqs) == 3  # a new frame each time, never a buffered one
    for t_request, out in answers:
        assert "error" not in out, out
        assert out["t_exposure_start"] >= out["t_trigger"] >= t_request
        assert (out["exposure_ms"], out["readout_ms"]) == (pytest.approx(5.0), pytest.approx(6.3))
    assert cam.grabs == 4  # the warm-up frame + one per request: the camera does not run free


def test_free_running_sources_and_software_trigger_refused_for_them():
    class Webcam(TriggerableCamera):
        can_trigger = False

    with pytest.raises(ValueError, match="cannot be software-triggered"):
        Acquisition([Webcam()], trigger="software")
    assert Acquisition([Webcam()], trigger="auto").triggered == {"t": False}
    assert Acquisition([TriggerableCamera()], trigger="free").triggered == {"t": False}


@pytest.mark.timeout(10)
def test_nearest_is_opt_in_and_refuses_a_frame_older_than_max_frame_age():
    cam = TriggerableCamera()
    with Acquisition([cam], trigger="free", fps=50) as acq:
        assert acq.wait_ready(5.0)
        assert VisionNode(acq).policy == "after"
        nearest = VisionNode(acq, noop_graph(), policy="nearest", max_frame_age_s=0.05)
        try:
            fresh = nearest.process("VisionRequest", "a", {"t_request": time.time()})
            old = nearest.process("VisionRequest", "b", {"t_request": time.time() + 1.0})  # newest is 1 s older
        finally:
            nearest.close()
    assert "error" not in fresh and fresh["frame_age_ms"] <= 50
    assert old["error"].startswith("stale frame: exposed") and "limit 50 ms" in old["error"]
    assert "t_exposure_start" in old and "frame_seq" in old
