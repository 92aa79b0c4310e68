"""run.mcap written from a run's records (a synthetic run, no processes): every robot and vision message of the
records, the arm from the acks or from the state stream, and a write that fails leaves no file at all."""

from __future__ import annotations

import errno
from collections import Counter

import numpy as np
import pytest

pytest.importorskip("mcap_protobuf")

from mcap.reader import make_reader  # noqa: E402
from mcap_protobuf.decoder import DecoderFactory  # noqa: E402

from aioadept.analysis.synthetic import synthetic_recorder  # noqa: E402
from aioadept.bus.messages import RobotState  # noqa: E402
from aioadept.record import mcapfile  # noqa: E402
from aioadept.record.mcapfile import ros2_string_cdr, write_run_mcap  # noqa: E402
from aioadept.robots import viper_s850 as kin  # noqa: E402


@pytest.fixture
def run():
    rec, params = synthetic_recorder(seed=3, n_steps=4)
    return rec.snapshot(metadata=params)


def _topics(path) -> Counter[str]:
    with open(path, "rb") as f:
        return Counter(ch.topic for _s, ch, _m in make_reader(f).iter_messages())


def _decoded(path, topic):
    with open(path, "rb") as f:
        return [p for _s, _c, _m, p in make_reader(f, decoder_factories=[DecoderFactory()])
                .iter_decoded_messages(topics=[topic])]


def test_every_message_of_the_records_is_in_the_file(run, tmp_path):
    assert write_run_mcap(run, tmp_path / "run.mcap") is None
    counts = _topics(tmp_path / "run.mcap")
    assert counts["/robot/command"] == len(run.robot)
    assert counts["/robot/ack"] == sum(r.acked for r in run.robot)
    assert counts["/vision/request"] == len(run.vision)
    assert counts["/vision/response"] == sum(v.answered for v in run.vision)
    assert counts["/robot_description"] == 1
    assert "/camera/image" not in counts and "/robot/state" not in counts  # no frames folder, no state stream
    assert [p.name for p in tmp_path.iterdir()] == ["run.mcap"]


def test_without_a_state_stream_the_arm_follows_the_acked_poses(tmp_path):
    rec, params = synthetic_recorder(seed=3, n_steps=4)
    run = rec.snapshot(metadata=params)
    assert write_run_mcap(run, tmp_path / "run.mcap") is None
    tf = _decoded(tmp_path / "run.mcap", "/tf")
    done = [r for r in run.robot if r.status == "done" and r.pose is not None]
    assert done and len(tf) % 6 == 0 and 0 < len(tf) <= 6 * len(done)
    assert [t.child_frame_id for t in tf[:6]] == ["link_1", "link_2", "link_3", "link_4", "link_5", "flange"]


def _composed(tfs) -> np.ndarray:
    """The transforms of a chain of FrameTransform messages composed, base to last (metres)."""
    m = np.eye(4)
    for t in tfs:
        x, y, z, w = t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w
        step = np.eye(4)
        step[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        step[:3, 3] = (t.translation.x, t.translation.y, t.translation.z)
        m = m @ step
    return m


def _state(t: float, joints) -> bytes:
    return RobotState(t_s=t, wall_time_s=t, joints_deg=tuple(joints), pose=kin.forward(joints)).to_bytes()


def test_the_state_stream_is_kept_raw_and_drives_the_arm(run, tmp_path):
    t0 = float(run.metadata["start_wall_epoch_s"])
    joints = [list(kin.HOME_JOINTS_DEG)] * 50 + [[10.0, -80.0, 170.0, 5.0, 80.0, 20.0]]
    payloads = [_state(t0 + 0.01 * i, q) for i, q in enumerate(joints)] + [b"\xff not a state"]
    assert write_run_mcap(run, tmp_path / "run.mcap", state=payloads) is None
    states = _decoded(tmp_path / "run.mcap", "/robot/state")
    assert [s.SerializeToString() for s in states] == payloads[:-1]  # as they came, the stranger's message left out
    tf = _decoded(tmp_path / "run.mcap", "/tf")
    # 0.5 s at 25 Hz: ~13 arm poses, and the last sample always
    assert 10 * 6 <= len(tf) <= 16 * 6
    last = tf[-6:]
    np.testing.assert_allclose(_composed(last)[:3, 3] * 1000.0, kin.flange_matrix(joints[-1])[:3, 3], atol=1e-6)


class _FillsUp:
    """A file that takes ``room`` bytes, then fails as a full disk does."""

    def __init__(self, f, room: int) -> None:
        self.f, self.room = f, room

    def write(self, data) -> int:
        self.room -= len(data)
        if self.room < 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        return self.f.write(data)

    def __getattr__(self, name):
        return getattr(self.f, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.f.close()


@pytest.mark.parametrize("room", [0, 100, 5000])
def test_a_full_disk_leaves_no_run_mcap_nor_its_temporary_file(run, tmp_path, monkeypatch, room):
    real_open = open
    monkeypatch.setattr(mcapfile, "open", lambda p, mode: _FillsUp(real_open(p, mode), room), raising=False)
    why = write_run_mcap(run, tmp_path / "run.mcap")
    assert why == "No space left on device"
    assert list(tmp_path.iterdir()) == []


def test_a_folder_that_is_gone_is_said_not_raised(run, tmp_path):
    why = write_run_mcap(run, tmp_path / "gone" / "run.mcap")
    assert why and "No such file" in why


def test_the_robot_description_is_a_ros2_string_in_cdr():
    data = ros2_string_cdr("<robot/>")
    assert data[:4] == b"\x00\x01\x00\x00"  # CDR, little endian
    n = int.from_bytes(data[4:8], "little")
    assert data[8:8 + n] == b"<robot/>\x00" and len(data) == 8 + n


def test_a_cobra_run_carries_the_cobras_urdf_and_its_state_drives_its_four_links(tmp_path):
    from aioadept.robots import model
    from aioadept.robots.urdf import urdf

    cobra = model("cobra-s600")
    rec, params = synthetic_recorder(seed=3, n_steps=2)
    run = rec.snapshot(metadata={**params, "cell": {"robot": {"model": "cobra-s600"}}})
    t0 = float(run.metadata["start_wall_epoch_s"])
    goal = (20.0, 60.0, 120.0, 30.0)
    payloads = [RobotState(t_s=t0 + i, wall_time_s=t0 + i, joints_deg=q, pose=cobra.forward(q)).to_bytes()
                for i, q in enumerate([cobra.home_deg, goal])]
    assert write_run_mcap(run, tmp_path / "run.mcap", state=payloads) is None
    with open(tmp_path / "run.mcap", "rb") as f:
        reader = make_reader(f)
        attachments = list(reader.iter_attachments())
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert [(a.name, a.data.decode()) for a in attachments] == [("cobra_s600.urdf", urdf(cobra))]
    assert meta["aioadept"]["robot_model"] == "cobra-s600"
    with open(tmp_path / "run.mcap", "rb") as f:
        desc = [m.data for _s, _c, m in make_reader(f).iter_messages(topics=["/robot_description"])]
    assert desc == [ros2_string_cdr(urdf(cobra))]
    tf = _decoded(tmp_path / "run.mcap", "/tf")
    assert [t.child_frame_id for t in tf[-4:]] == ["link_1", "link_2", "link_3", "flange"]
    assert len(tf) == 8  # both samples (the last is always drawn), four links each
    np.testing.assert_allclose(_composed(tf[-4:])[:3, 3] * 1000.0, cobra.flange_matrix(goal)[:3, 3], atol=1e-6)
