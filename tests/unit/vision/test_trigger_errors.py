"""A software-triggered grab that fails (a GigE camera's timeout, lost frame, vanished camera) is answered at once
with the camera's own error, not after the request's frame timeout with a generic "no frame"."""

from __future__ import annotations

import time

import numpy as np
import pytest

from aioadept.errors import VisionError
from aioadept.vision.acquisition import Acquisition
from aioadept.vision.node import VisionNode, noop_graph
from aioadept.vision.sources import Camera, Frame


class FlakyCamera(Camera):
    """Triggerable; the first grab succeeds (wait_ready), later grabs fail while ``broken`` is set."""

    can_trigger = True

    def __init__(self) -> None:
        self.camera_id = "flaky"
        self.broken = False
        self.seq = 0

    def grab(self) -> Frame:
        if self.broken:
            raise VisionError("GigE camera 10.0.0.9: frame lost (missing-packets)")
        self.seq += 1
        return Frame(np.zeros((4, 4), np.uint8), time.time(), self.camera_id, self.seq - 1)


@pytest.mark.timeout(10)
def test_a_failed_triggered_grab_raises_its_error_at_once_in_a_blocking_wait():
    cam = FlakyCamera()
    with Acquisition([cam], trigger="software") as acq:
        assert acq.wait_ready(5.0)
        cam.broken = True
        t0 = time.monotonic()
        with pytest.raises(VisionError, match="frame lost"):
            acq.frame_at(time.time(), timeout_s=5.0)
        assert time.monotonic() - t0 < 2.0  # not the 5 s timeout
        cam.broken = False  # a later request is not poisoned by the old failure
        assert acq.frame_at(time.time(), timeout_s=5.0).seq == 1


@pytest.mark.timeout(10)
async def test_the_node_answers_a_failed_triggered_grab_with_the_cameras_error_at_once():
    cam = FlakyCamera()
    with Acquisition([cam], trigger="software") as acq:
        assert acq.wait_ready(5.0)
        node = VisionNode(acq, noop_graph(), timeout_s=5.0)
        try:
            cam.broken = True
            t0 = time.monotonic()
            out = await node.handle("VisionRequest", "x", {"t_request": time.time()})
            assert time.monotonic() - t0 < 2.0
            assert "frame lost (missing-packets)" in out["error"]
            assert acq.stats()[0].errors == 1
            cam.broken = False
            out = await node.handle("VisionRequest", "y", {"t_request": time.time()})
            assert "error" not in out and out["frame_seq"] == 1
        finally:
            node.close()
