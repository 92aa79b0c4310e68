"""What CellLogger writes, read back through Rerun's own reader: entity paths, counts, values at known times."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rerun")

import rerun as rr  # noqa: E402

from aioadept.geometry import Pose  # noqa: E402
from aioadept.record.read import read_rrd  # noqa: E402
from aioadept.record.rrd import IMAGE_MAX_WIDTH, CellLogger  # noqa: E402
from aioadept.robots import viper_s850 as kin  # noqa: E402

pytestmark = pytest.mark.timeout(60)

OFFSET = 1_700_000_000.0  # loop clock 0 = this epoch second


def _record(path, fill):
    rec = rr.RecordingStream("aioadept-test")
    rec.set_sinks(rr.FileSink(str(path)))
    lg = CellLogger(rec, loop_to_epoch_s=OFFSET)
    fill(lg)
    rec.flush()
    rec.disconnect()
    return read_rrd(path), lg


def test_commands_acks_and_spans(tmp_path):
    home = kin.forward(kin.HOME_JOINTS_DEG)

    def fill(lg):
        lg.command("a1", "move_joints", kin.HOME_JOINTS_DEG, 1.0)
        lg.command("a2", "break", (), 1.0)
        lg.ack("a1", "move_joints", "done", home, 1.5)
        lg.ack("a2", "break", "done", home, 2.0)
        lg.command("a3", "move_rel_tool", (0, 0, 2.0, 0, 0, 0), 3.0)
        lg.ack("a3", "move_rel_tool", "error", home, 3.25, error="JOINT_LIMIT")

    rows, lg = _record(tmp_path / "r.rrd", fill)
    texts = [r["TextLog:text"][0] for r in rows["/messages/robot"]]
    assert texts[0].startswith("-> a1 move_joints(0, -90, 180, 0, 90, 0)")
    assert any(t.startswith("<- a1 move_joints done 500.0 ms") for t in texts)
    assert any("error" in t and "JOINT_LIMIT" in t for t in texts)
    assert len(texts) == 6
    levels = {r["TextLog:text"][0]: r["TextLog:level"][0] for r in rows["/messages/robot"]}
    assert levels[next(t for t in texts if "JOINT_LIMIT" in t)] == "WARN"
    # the Gantt row: in flight 0->1->2 at t=1, 2->1 at 1.5, 1->0 at 2, 0->1 at 3, 1->0 at 3.25
    span = [(round(r["time"] - OFFSET, 6), r["Scalars:scalars"][0]) for r in rows["/timeline/robot_in_flight"]]
    assert span == [(1, 0), (1, 1), (1, 1), (1, 2), (1.5, 2), (1.5, 1), (2, 1), (2, 0),
                    (3, 0), (3, 1), (3.25, 1), (3.25, 0)]
    acks = [r["Scalars:scalars"][0] for r in rows["/timeline/robot_ack_ms"]]
    assert acks == pytest.approx([500.0, 1000.0, 250.0])
    # the commanded targets: the home pose of move_joints, then 2 mm along the tool z of the acked pose
    targets = rows["/world/targets"][-1]["Points3D:positions"]
    np.testing.assert_allclose(targets[0], home.position_mm, atol=1e-3)
    z_axis = home.to_matrix()[:3, 2]
    np.testing.assert_allclose(targets[1], home.position_mm + 2.0 * z_axis, atol=1e-3)
    # the arm, from the acked pose by IK (no state stream), ends at the tool
    links = rows["/world/robot/links"][-1]["LineStrips3D:strips"][0]
    np.testing.assert_allclose(links[-1], home.position_mm, atol=1e-3)
    tool = rows["/world/robot/tool"]
    assert any(r.get("Transform3D:translation") for r in tool)
    assert lg.counts == {"command": 3, "ack": 3}


def test_targets_of_the_straight_line_and_approach_skills(tmp_path):
    home = kin.forward(kin.HOME_JOINTS_DEG)  # tool down: -Z of the tool is world up
    p = Pose(400, 0, 400, 0, 180, 0)

    def fill(lg):
        lg.ack("h", "here", "done", home, 0.5)
        lg.command("b1", "move_to_s", p.as_tuple(), 1.0)
        lg.command("b2", "appros", (*p.as_tuple(), 50.0), 1.1)
        lg.command("b3", "departs", (30.0,), 1.2)
        lg.command("b4", "move_rel_tool_s", (0, 0, 10.0, 0, 0, 0), 1.3)

    rows, _ = _record(tmp_path / "l.rrd", fill)
    targets = rows["/world/targets"][-1]["Points3D:positions"]
    np.testing.assert_allclose(targets, [(400, 0, 400), (400, 0, 450), home.position_mm + (0, 0, 30),
                                         home.position_mm - (0, 0, 10)], atol=1e-3)


def test_vision_sharpness_frames_and_focus_plane(tmp_path):
    pose0 = Pose(100, 200, 300, 0, 180, 0)
    series = [10.0, 20.0, 30.0, 25.0]

    def fill(lg):
        lg.ack("h", "here", "done", pose0, 0.5)
        for i, s in enumerate(series):
            lg.request(f"v{i}", "VisionRequest", {}, 1.0 + i)
            frame_t = OFFSET + 1.0 + i - 0.01
            lg.response(f"v{i}", "VisionResponse", {"sharpness": s, "frame_t": frame_t, "frame_age_ms": 10.0},
                        1.05 + i)
            lg.frame(np.full((480, 640), 10 * i, np.uint8), frame_t, step=i)
        lg.mark("retract", 4, 5.0)

    rows, lg = _record(tmp_path / "v.rrd", fill)
    sharp = rows["/focus/sharpness"]
    assert [r["Scalars:scalars"][0] for r in sharp] == series
    assert [r["step"] for r in sharp] == [0, 1, 2, 3]
    # each sharpness sits at its frame's exposure time, not at the response's arrival
    assert [r["time"] - OFFSET for r in sharp] == pytest.approx([0.99, 1.99, 2.99, 3.99], abs=1e-6)
    assert [r["Scalars:scalars"][0] for r in rows["/timeline/vision_response_ms"]] == pytest.approx([50.0] * 4)
    assert len(rows["/messages/vision"]) == 8
    assert "sharpness=30.000" in rows["/messages/vision"][5]["TextLog:text"][0]
    images = rows["/camera/image"]
    assert len(images) == 4
    assert [r["time"] for r in images] == pytest.approx([r["time"] for r in sharp])
    # downsampled: a JPEG of at most IMAGE_MAX_WIDTH columns (decode it back)
    import cv2

    blob = np.asarray(images[2]["EncodedImage:blob"][0], dtype=np.uint8)
    img = cv2.imdecode(blob, cv2.IMREAD_UNCHANGED)
    assert img.shape[1] <= IMAGE_MAX_WIDTH and abs(int(img.mean()) - 20) <= 2
    plane = rows["/world/focus_plane"]
    assert len(plane) == 1
    np.testing.assert_allclose(plane[0]["Boxes3D:centers"][0], pose0.position_mm, atol=1e-3)
    assert plane[0]["time"] - OFFSET == pytest.approx(5.0)
    assert any("focus plane" in r["TextLog:text"][0] for r in rows["/messages/app"])


def test_a_vision_error_is_a_warning_and_no_sharpness(tmp_path):
    def fill(lg):
        lg.request("v0", "VisionRequest", {}, 1.0)
        lg.response("v0", "VisionResponse", {"error": "no object"}, 1.1)

    rows, _ = _record(tmp_path / "e.rrd", fill)
    assert "/focus/sharpness" not in rows
    last = rows["/messages/vision"][-1]
    assert last["TextLog:level"] == ["WARN"] and "no object" in last["TextLog:text"][0]


def test_a_cobra_run_carries_its_urdf_joint_names_and_arm(tmp_path):
    from aioadept.robots import model
    from aioadept.robots.urdf import urdf

    cobra = model("cobra-s600")
    goal = (10.0, 70.0, 120.0, 0.0)

    def fill(lg):
        lg.command("c1", "move_joints", (*goal, 0.0, 0.0), 1.0)
        lg.ack("c1", "move_joints", "done", cobra.forward(goal), 1.5)

    rec = rr.RecordingStream("aioadept-test")
    rec.set_sinks(rr.FileSink(str(tmp_path / "c.rrd")))
    lg = CellLogger(rec, loop_to_epoch_s=OFFSET, arm=cobra)
    fill(lg)
    rec.flush()
    rec.disconnect()
    rows = read_rrd(tmp_path / "c.rrd")
    assert rows["/robot/urdf"][0]["TextDocument:text"] == [urdf(cobra)]
    series = rows["/robot/joints_deg"]
    assert [r["SeriesLines:names"] for r in series if "SeriesLines:names" in r] == [
        ["joint_1", "joint_2", "joint_3", "joint_4"]]
    target = rows["/world/targets"][-1]["Points3D:positions"][0]
    np.testing.assert_allclose(target, cobra.forward(goal).position_mm, atol=1e-3)
    joints = rows["/world/robot/joints"][-1]
    assert joints["Points3D:labels"] == ["base", "joint_1", "joint_2", "joint_3", "flange"]
    np.testing.assert_allclose(joints["Points3D:positions"][-1], cobra.forward(goal).position_mm, atol=1e-3)
    assert [r["Scalars:scalars"] for r in series if "Scalars:scalars" in r][-1] == pytest.approx(goal, abs=1e-6)


def test_a_cells_recording_draws_the_cells_arm(tmp_path):
    """open_run_recording (what focus and pickplace call) hands the cell file's [robot] model to the recording."""
    from aioadept.cell.config import CellConfig
    from aioadept.runs.capture import Recorder
    from aioadept.record.hook import open_run_recording

    from pathlib import Path

    cfg = CellConfig.from_toml(Path(__file__).resolve().parents[3] / "examples" / "cobra-pickplace.toml")
    cfg.robot.state_endpoint = "none"
    rec = open_run_recording(cfg, tmp_path, Recorder())
    try:
        assert rec.logger.arm.name == "cobra-s600"
    finally:
        rec.close()
    rows = read_rrd(tmp_path / "run.rrd")
    assert "cobra-s600" in rows["/robot/urdf"][0]["TextDocument:text"][0]
