"""run.mcap of a real demo run (the demo's sim and vision node processes, fast time scale): read back with the MCAP
library and Foxglove's Protobuf schemas, its message counts match robot.csv and vision.csv of the same folder, its
arm is our forward kinematics, and the pinned Rerun's own MCAP reader (``rerun mcap convert``) understands it."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mcap_protobuf")
pytest.importorskip("foxglove_schemas_protobuf")

from mcap.reader import make_reader  # noqa: E402
from mcap_protobuf.decoder import DecoderFactory  # noqa: E402

from aioadept.bus.messages import EventMessage, RobotState  # noqa: E402
from aioadept.geometry import Pose  # noqa: E402
from aioadept.robots import viper_s850 as kin  # noqa: E402
from aioadept.robots.viper_s850_urdf import FLANGE_LINK, urdf  # noqa: E402

BIN = Path(sys.executable).parent


def _demo(out: Path, *extra: str) -> Path:
    env = {**os.environ, "COLUMNS": "120"}
    proc = subprocess.run([str(BIN / "aioadept"), "demo", "--time-scale", "20", "--no-analyze", "--out", str(out),
                           *extra], capture_output=True, text=True, timeout=100, env=env, stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = [p for p in out.iterdir() if p.is_dir()]
    return run_dir


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def _metres(m_mm: np.ndarray) -> np.ndarray:
    m = m_mm.copy()
    m[:3, 3] /= 1000.0
    return m


def _quat_matrix(q) -> np.ndarray:
    x, y, z, w = q.x, q.y, q.z, q.w
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory) -> Path:
    return _demo(tmp_path_factory.mktemp("mcap") / "runs")


@pytest.mark.timeout(120)
def test_run_mcap_holds_every_message_of_robot_csv_and_vision_csv(demo_run):
    robot = _rows(demo_run / "robot.csv")
    vision = _rows(demo_run / "vision.csv")
    assert robot and vision
    counts: Counter[str] = Counter()
    schemas: dict[str, tuple[str, str]] = {}
    with (demo_run / "run.mcap").open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, _ in reader.iter_messages():
            schemas[channel.topic] = (schema.name, schema.encoding)
            counts[channel.topic] += 1
        attachments = list(reader.iter_attachments())
        summary = reader.get_summary()
    assert schemas == {
        "/robot_description": ("std_msgs/msg/String", "ros2msg"),
        "/robot/command": ("foxglove.Log", "protobuf"), "/robot/ack": ("foxglove.Log", "protobuf"),
        "/tf": ("foxglove.FrameTransform", "protobuf"),
        "/vision/request": ("epypes.Event", "protobuf"), "/vision/response": ("epypes.Event", "protobuf"),
        "/camera/image": ("foxglove.CompressedImage", "protobuf"),
        "/robot/state": ("aioadept.RobotState", "protobuf"),
    }
    assert counts["/robot/command"] == len(robot)
    assert counts["/robot/ack"] == sum(1 for r in robot if r["t_recv_s"])
    assert counts["/vision/request"] == len(vision)
    assert counts["/vision/response"] == sum(1 for v in vision if v["t_recv_s"])
    assert counts["/camera/image"] == sum(1 for v in vision if v["frame_seq"] and not v["error"])
    assert counts["/robot_description"] == 1
    assert counts["/tf"] > 0 and counts["/tf"] % 6 == 0  # six links per arm pose
    # the sim's state stream (100 Hz) over the run: every sample, decimated to 25 Hz for /tf
    assert counts["/robot/state"] > counts["/tf"] / 6
    assert summary.statistics.message_count == sum(counts.values())
    assert [a.name for a in attachments] == ["viper_s850.urdf"]
    assert attachments[0].data.decode() == urdf()
    # the run's temporary file is gone: only the complete file under its name
    assert not [p.name for p in demo_run.iterdir() if p.name.startswith(".")]


@pytest.mark.timeout(120)
def test_the_decoded_messages_are_the_run_ids_sharpness_frames_and_arm(demo_run):
    robot = _rows(demo_run / "robot.csv")
    vision = _rows(demo_run / "vision.csv")
    decoded: dict[str, list] = {}
    with (demo_run / "run.mcap").open("rb") as f:
        for _s, channel, message, proto in make_reader(f, decoder_factories=[DecoderFactory()]) \
                .iter_decoded_messages(topics=["/robot/command", "/vision/response", "/camera/image", "/tf",
                                               "/robot/state"]):
            decoded.setdefault(channel.topic, []).append((message.log_time, proto))
    # commands in send order, each naming its id and skill, stamped at its send time
    cmd = decoded["/robot/command"]
    assert [c.message.split()[1:3] for _t, c in cmd] == [[r["id"], r["skill"]] for r in robot]
    # responses carry the sharpness the node measured (the bus's own Event, as on the wire)
    answered = [v for v in vision if v["t_recv_s"]]
    resp = decoded["/vision/response"]
    assert [r.id for _t, r in resp] == [v["id"] for v in answered]
    assert [r.type for _t, r in resp] == [v["response_type"] for v in answered]
    events = [EventMessage.from_bytes(r.SerializeToString()) for _t, r in resp]  # the bus's own decoder reads them
    sharp = [e.attributes["sharpness"] for e in events]
    assert sharp == pytest.approx([float(v["sharpness"]) for v in answered])
    # each frame is a PNG stamped at its exposure time
    imgs = decoded["/camera/image"]
    assert all(i.format == "png" and i.data[:8] == b"\x89PNG\r\n\x1a\n" for _t, i in imgs)
    with_frame = [v for v in answered if v["frame_seq"] and not v["error"]]
    assert [i.timestamp.ToNanoseconds() / 1e9 for _t, i in imgs] == pytest.approx(
        sorted(float(v["frame_t_epoch_s"]) for v in with_frame), abs=1e-6)
    # the last arm pose: the six link transforms compose to the flange of the last acked pose
    tf = decoded["/tf"][-6:]
    assert [t.child_frame_id for _t, t in tf][-1] == FLANGE_LINK
    m = np.eye(4)
    for _t, t in tf:
        step = np.eye(4)
        step[:3, :3] = _quat_matrix(t.rotation)
        step[:3, 3] = (t.translation.x, t.translation.y, t.translation.z)
        m = m @ step
    # ... which is the flange of the last state sample's joints (the raw bytes read by the bus's own decoder)
    last_state = RobotState.from_bytes(decoded["/robot/state"][-1][1].SerializeToString())
    np.testing.assert_allclose(m, _metres(kin.flange_matrix(last_state.joints_deg)), atol=1e-9)
    last = [r for r in robot if r["status"] == "done" and r["pose_x_mm"]][-1]
    pose = Pose(*(float(last[k]) for k in ("pose_x_mm", "pose_y_mm", "pose_z_mm", "pose_yaw_deg",
                                             "pose_pitch_deg", "pose_roll_deg")))
    np.testing.assert_allclose(m[:3, 3] * 1000.0, [pose.x, pose.y, pose.z], atol=1e-3)
    np.testing.assert_allclose(m[:3, :3], pose.to_matrix()[:3, :3], atol=1e-6)
    # each topic's log times are in order
    for topic, msgs in decoded.items():
        assert [t for t, _m in msgs] == sorted(t for t, _m in msgs), topic


@pytest.mark.timeout(120)
def test_rerun_reads_run_mcap_as_text_logs_images_transforms_and_the_urdf(demo_run, tmp_path):
    pytest.importorskip("rerun")
    from aioadept.record.read import read_rrd

    rerun = BIN / "rerun"
    env = {**os.environ, "RERUN_ANALYTICS": "0", "HOME": str(tmp_path), "XDG_CONFIG_HOME": str(tmp_path / "cfg"),
           "XDG_DATA_HOME": str(tmp_path / "data")}
    check = subprocess.run([str(rerun), "mcap", "check", str(demo_run / "run.mcap")], capture_output=True, text=True,
                           timeout=60, env=env, stdin=subprocess.DEVNULL)
    assert check.returncode == 0, check.stdout + check.stderr
    out = tmp_path / "from_mcap.rrd"
    conv = subprocess.run([str(rerun), "mcap", "convert", str(demo_run / "run.mcap"), "-o", str(out)],
                          capture_output=True, text=True, timeout=60, env=env, stdin=subprocess.DEVNULL)
    assert conv.returncode == 0, conv.stderr[-3000:]
    rows = read_rrd(out)

    def with_(entity: str, column: str) -> list:
        return [r for r in rows[entity] if r.get(column) is not None]

    robot = _rows(demo_run / "robot.csv")
    vision = _rows(demo_run / "vision.csv")
    # Foxglove's schemas become Rerun's own archetypes, one row per message
    assert len(with_("/robot/command", "TextLog:text")) == len(robot)
    assert len(with_("/robot/ack", "TextLog:text")) == sum(1 for r in robot if r["t_recv_s"])
    assert len(with_("/camera/image", "EncodedImage:blob")) == sum(
        1 for v in vision if v["frame_seq"] and not v["error"])
    assert len(with_("/tf", "Transform3D:translation")) % 6 == 0
    assert len(with_("/vision/response", "epypes.Event:message")) == sum(1 for v in vision if v["t_recv_s"])
    # the URDF on /robot_description is drawn: one visual per link that has a segment
    visuals = {e for e in rows if e.startswith("/viper_s850/visual_geometries/")}
    assert {e.split("/")[3] for e in visuals} == {"base_link", "link_1", "link_2", "link_3", "link_4", "link_5"}
