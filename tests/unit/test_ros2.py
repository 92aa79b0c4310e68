"""aioadept.bus.ros2 against an independent ROS 2 message library (rosbags): the JointState CDR is byte for byte
what rosbags writes and reads back to the same values, the type hash is the one rosbags computes, and the attachment
has the layout rmw_zenoh_cpp reads (sequence, time, GID: 33 bytes)."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.bus import ros2
from aioadept.errors import BusError

rosbags = pytest.importorskip("rosbags.typesys", reason="rosbags (the test extra) checks the ROS 2 encoding")
zenoh = pytest.importorskip("zenoh", reason="the [zenoh] extra writes rmw_zenoh's attachment")

TYPE = "sensor_msgs/msg/JointState"


@pytest.fixture(scope="module")
def store():
    return rosbags.get_typestore(rosbags.Stores.ROS2_JAZZY)


def _reference(store, stamp_s, names, position, velocity, effort, frame_id):
    import numpy as np

    Time = store.types["builtin_interfaces/msg/Time"]
    Header = store.types["std_msgs/msg/Header"]
    JointState = store.types[TYPE]
    sec = math.floor(stamp_s)
    nanosec = min(int(round((stamp_s - sec) * 1e9)), 999_999_999)
    msg = JointState(header=Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame_id), name=list(names),
                     position=np.array(position, dtype=np.float64), velocity=np.array(velocity, dtype=np.float64),
                     effort=np.array(effort, dtype=np.float64))
    return bytes(store.serialize_cdr(msg, TYPE))


def test_the_type_hash_is_ros2s(store) -> None:
    assert store.hash_rihs01(TYPE) == ros2.JOINT_STATE_HASH
    # and a hash known from ROS 2 itself (std_msgs/String, as `ros2 topic info -v` prints it): rosbags computes it right
    assert store.hash_rihs01("std_msgs/msg/String") == \
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"


finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
names = st.lists(st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=12), max_size=7)


@settings(max_examples=200, deadline=None)
@given(stamp=st.floats(0, 2**31 - 2), names=names, data=st.data(),
       frame=st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=9))
def test_joint_state_bytes_are_rosbags_bytes(store, stamp, names, data, frame) -> None:
    n = len(names)
    position = data.draw(st.lists(finite, min_size=n, max_size=n))
    velocity = data.draw(st.one_of(st.just([]), st.lists(finite, min_size=n, max_size=n)))
    effort = data.draw(st.one_of(st.just([]), st.lists(finite, min_size=n, max_size=n)))
    ours = ros2.encode_joint_state(stamp, names, position, velocity, effort, frame_id=frame)
    assert ours == _reference(store, stamp, names, position, velocity, effort, frame)
    back = store.deserialize_cdr(ours, TYPE)
    assert back.name == names and list(back.position) == position and back.header.frame_id == frame
    assert list(back.velocity) == velocity and list(back.effort) == effort
    assert abs(back.header.stamp.sec + back.header.stamp.nanosec * 1e-9 - stamp) < 1e-6 * max(1.0, stamp) ** 0.5


def test_viper_state_decodes_in_radians(store) -> None:
    enc = ros2.encode_joint_state(1764270000.25, ("joint_1", "joint_2"), [math.radians(90), math.radians(-45)])
    msg = store.deserialize_cdr(enc, TYPE)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1764270000, 250_000_000)
    assert msg.position.tolist() == pytest.approx([math.pi / 2, -math.pi / 4])
    assert enc[:4] == b"\x00\x01\x00\x00"  # little-endian plain CDR


def test_bad_values_are_refused() -> None:
    with pytest.raises(BusError, match="2 values for 1 joints"):
        ros2.encode_joint_state(1.0, ["a"], [1.0, 2.0])
    with pytest.raises(BusError, match="stamp"):
        ros2.encode_joint_state(math.nan, ["a"], [1.0])
    with pytest.raises(BusError, match="NUL"):
        ros2.encode_joint_state(1.0, ["a\x00b"], [1.0])


def test_attachment_is_rmw_zenohs_33_bytes() -> None:
    gid = bytes(range(16))
    att = ros2.attachment(7, 1_700_000_000_123_456_789, gid)
    assert len(att) == 33
    assert struct.unpack_from("<qq", att) == (7, 1_700_000_000_123_456_789)
    assert att[16] == 16 and att[17:] == gid  # LEB128 length of the GID, then the GID
    with pytest.raises(BusError, match="16 bytes"):
        ros2.attachment(1, 1, b"short")


def test_topic_key() -> None:
    assert ros2.topic_key("/joint_states") == \
        "0/joint_states/sensor_msgs::msg::dds_::JointState_/" + ros2.JOINT_STATE_HASH
    assert ros2.topic_key("/cell1/r1/joint_states", domain_id=7).startswith("7/cell1/r1/joint_states/")
    for bad in ("", "/", "/2d", "/a//b", "/a-b", "/joint states"):
        with pytest.raises(BusError, match="ROS 2 topic"):
            ros2.topic_key(bad)
    with pytest.raises(BusError, match="domain"):
        ros2.topic_key("/x", domain_id=300)
