"""The part locator node answering LocateRequests over real ZeroMQ on 127.0.0.1: in-process (LocatorNode behind its
Responder) and as ``aioadept vision --graph locate`` (a subprocess), with a synthetic view of known truth."""

from __future__ import annotations

import math
import time

import cv2
import pytest

from aioadept.bus.communicator import Communicator
from aioadept.errors import RequestTimeout
from aioadept.bus.located import LOCATE_REQUEST, parts_from_attributes
from aioadept.testing.nodes import running_node
from aioadept.vision.calibration import CameraCalibration, write_calibration
from aioadept.vision.synthetic import SyntheticPart, render

CAL = CameraCalibration()
TRUTH = [SyntheticPart(400.0, 60.0, 20.0, (40.0, 40.0, 20.0), marker=4),
         SyntheticPart(500.0, -70.0, -35.0, (40.0, 40.0, 20.0), marker=11),
         SyntheticPart(360.0, -110.0, 50.0, (50.0, 30.0, 20.0), (40, 70, 200))]


def check_parts(attributes: dict) -> None:
    parts = parts_from_attributes(attributes)
    assert [(p.kind, p.marker, p.colour) for p in parts] == [("marker", 4, ""), ("marker", 11, "")]
    for p, t in zip(parts, TRUTH[:2], strict=True):  # the two markers; the third part has none
        assert math.hypot(p.x_mm - t.x_mm, p.y_mm - t.y_mm) <= 1.0 and abs(p.yaw_deg - t.yaw_deg) <= 1.0, (p, t)


@pytest.fixture
def view_folder(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    cv2.imwrite(str(folder / "0.png"), render(CAL, TRUTH, seed=1))
    return folder


@pytest.mark.timeout(30)
async def test_locate_requests_and_bad_ones_over_zeromq_and_the_node_stays_usable(view_folder):
    from aioadept.vision.acquisition import Acquisition
    from aioadept.vision.locate_node import LocatorNode, locate_responder
    from aioadept.vision.sources import ImageFolderSource

    with Acquisition([ImageFolderSource(view_folder, loop=True)], fps=50) as acq:
        node = LocatorNode(acq, CAL, hyperparameters={"height_mm": 20.0}, policy="nearest", max_frame_age_s=1.0)
        try:
            async with locate_responder("tcp://127.0.0.1:0", "tcp://127.0.0.1:0", node) as responder:
                async with Communicator(responder.peer_request_endpoint, responder.peer_response_endpoint,
                                        timeout_s=5.0) as comm:
                    ok = await comm.request(LOCATE_REQUEST, {"t_request": time.time()})
                    blue = await comm.request(LOCATE_REQUEST, {"colour": "blue"})
                    bad = [await comm.request(LOCATE_REQUEST, attrs) for attrs in
                           ({"height_mm": float("inf")}, {"colour": 3}, {"marker_mm": -1.0},
                            {"marker": -2})]
                    # a sharpness request is not this node's: ignored, no answer (the requester times out)
                    with pytest.raises(RequestTimeout):
                        await comm.request("VisionRequest", {}, timeout_s=0.5)
                    again = await comm.request(LOCATE_REQUEST, {"marker": 11})
        finally:
            node.close()
    assert ok.event_type == "LocateResponse" and "error" not in ok.attributes, ok.attributes
    check_parts(ok.attributes)
    (b,) = parts_from_attributes(blue.attributes)
    assert b.colour == "blue" and math.hypot(b.x_mm - 360.0, b.y_mm + 110.0) <= 1.0
    for answer, word in zip(bad, ("height_mm", "colour", "marker_mm", "marker"), strict=True):
        assert answer.error is not None and answer.error.startswith("bad request") and word in answer.error
        assert "parts" not in answer.attributes
    assert [p.marker for p in parts_from_attributes(again.attributes)] == [11]
    assert responder.ignored >= 1  # (the requester re-publishes an unanswered request once)


@pytest.mark.timeout(60)
async def test_aioadept_vision_graph_locate_serves_the_cell_files_calibration(tmp_path, view_folder):
    cell = tmp_path / "cell.toml"
    cell.write_text('[vision]\ngraph = "locate"\npart_height_mm = 20.0\nstate_endpoint = "none"\n',
                    encoding="utf-8")
    write_calibration(cell, CAL)
    async with running_node("vision", "--config", str(cell), "--source", f"folder:{view_folder}",
                            "--request-endpoint", "tcp://127.0.0.1:0", "--response-endpoint", "tcp://127.0.0.1:0",
                            log_path=tmp_path / "vision.log", expect_clean_exit=False) as node:
        assert node.ready["graph"] == "locate"
        async with Communicator(node.ready["request"], node.ready["response"], timeout_s=10.0) as comm:
            answer = await comm.request(LOCATE_REQUEST, {})
            bad = await comm.request(LOCATE_REQUEST, {"colour": "purple"})
            again = await comm.request(LOCATE_REQUEST, {})
    assert "error" not in answer.attributes, answer.attributes
    check_parts(answer.attributes)
    assert bad.error.startswith("bad request: colour")
    check_parts(again.attributes)


@pytest.mark.timeout(30)
def test_aioadept_vision_graph_locate_refuses_a_bad_calibration_in_one_line(tmp_path):
    import subprocess
    import sys

    cell = tmp_path / "cell.toml"
    cell.write_text("[calibration]\nfx_px = -3.0\n", encoding="utf-8")
    for args, word in [(["--calibration", str(cell)], "fx_px"), ([], "needs --calibration"),
                       (["--calibration", str(tmp_path / "none.toml")], "no such file")]:
        res = subprocess.run([sys.executable, "-m", "aioadept", "vision", "--graph", "locate", *args],
                             capture_output=True, text=True, timeout=20)
        assert res.returncode == 2, res.stderr
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and word in lines[0], res.stderr
