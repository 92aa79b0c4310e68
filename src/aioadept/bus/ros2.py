"""The robot state on ROS 2's wire: ``sensor_msgs/msg/JointState`` in CDR, put on the Zenoh key expression that
ROS 2's Zenoh middleware (``rmw_zenoh_cpp``, Jazzy and later) uses for a topic, with the attachment it requires.

A ROS 2 node on ``rmw_zenoh_cpp`` that subscribes to ``/joint_states`` (``ros2 topic echo /joint_states
sensor_msgs/msg/JointState``, RViz's robot model through ``robot_state_publisher``) declares a Zenoh subscriber on

    <domain>/<topic without its outer "/">/sensor_msgs::msg::dds_::JointState_/RIHS01_a13ee3a3...

and takes each sample whose payload is the message in CDR (little endian, with its 4-byte encapsulation header) and
whose attachment is the publisher's sequence number (int64, from 1), source time (int64 ns since the epoch) and GID
(16 bytes), written by Zenoh's own serializer (``zenoh.ext.z_serialize``: 33 bytes). Without the attachment
rmw_zenoh drops the sample. The type hash is ROS 2's RIHS01 of the message definition (Jazzy, Kilted, Rolling);
Humble's rmw_zenoh has no hash in its keys and is not served.

What is not done: the graph's liveliness tokens (``@ros2_lv/...``), so ``ros2 topic list`` does not show the topic
(a subscriber that names the type receives it all the same), and QoS beyond Zenoh's defaults (best effort to a late
joiner: no history). docs/bus.md, "ROS 2", says what was checked here and how.

Joint names are the URDF's (:mod:`aioadept.robots.viper_s850_urdf`: ``joint_1`` .. ``joint_6``), positions in
radians as ROS wants them (the V+ joint angles, converted), stamped with the state's own ``wall_time_s``.
"""

from __future__ import annotations

import math
import os
import re
import struct
import time
from collections.abc import Sequence
from typing import Any

from aioadept.errors import BusError

__all__ = ["JOINT_STATE_DDS_TYPE", "JOINT_STATE_HASH", "JointStatePublisher", "attachment", "encode_joint_state",
           "topic_key"]

JOINT_STATE_DDS_TYPE = "sensor_msgs::msg::dds_::JointState_"
JOINT_STATE_HASH = "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
"""RIHS01 of ``sensor_msgs/msg/JointState`` (the same on Jazzy, Kilted and Rolling; tests/unit/test_ros2.py computes
it again with rosbags)."""

_ROS_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_CDR_LE = b"\x00\x01\x00\x00"  # encapsulation: plain CDR, little endian, no options


def topic_key(topic: str, *, domain_id: int = 0, dds_type: str = JOINT_STATE_DDS_TYPE,
              type_hash: str = JOINT_STATE_HASH) -> str:
    """The key expression rmw_zenoh publishes ``topic`` (a ROS name, e.g. ``/joint_states``) on; BusError for a
    name ROS would refuse."""
    if not isinstance(domain_id, int) or not 0 <= domain_id <= 232:
        raise BusError(f"ROS 2 domain id {domain_id!r}: expected an integer 0..232")
    name = topic.strip("/")
    if not all(_ROS_TOKEN.match(p) for p in name.split("/")):
        raise BusError(f"ROS 2 topic {topic!r}: expected a name like /joint_states (letters, digits, '_', "
                       f"separated by '/', each part not starting with a digit)")
    return f"{domain_id}/{name}/{dds_type}/{type_hash}"


class _Cdr:
    """A little-endian CDR writer for the few types JointState needs; alignment counts from after the
    encapsulation header, as CDR's does."""

    def __init__(self) -> None:
        self.buf = bytearray()

    def _align(self, n: int) -> None:
        self.buf += b"\x00" * (-len(self.buf) % n)

    def int32(self, v: int) -> None:
        self._align(4)
        self.buf += struct.pack("<i", v)

    def uint32(self, v: int) -> None:
        self._align(4)
        self.buf += struct.pack("<I", v)

    def string(self, s: str) -> None:
        data = s.encode()
        if b"\x00" in data:
            raise BusError(f"a ROS 2 string cannot hold a NUL: {s!r}")
        self.uint32(len(data) + 1)
        self.buf += data + b"\x00"

    def strings(self, items: Sequence[str]) -> None:
        self.uint32(len(items))
        for s in items:
            self.string(s)

    def float64s(self, values: Sequence[float]) -> None:
        self.uint32(len(values))
        if values:
            self._align(8)
            self.buf += struct.pack(f"<{len(values)}d", *values)


def encode_joint_state(stamp_s: float, names: Sequence[str], position: Sequence[float],
                       velocity: Sequence[float] = (), effort: Sequence[float] = (), *, frame_id: str = "") -> bytes:
    """``sensor_msgs/msg/JointState`` as CDR bytes (with the encapsulation header): ``header.stamp`` from
    ``stamp_s`` (seconds since the epoch), each array as given (ROS allows an empty velocity or effort)."""
    if not math.isfinite(stamp_s) or stamp_s < 0:
        raise BusError(f"JointState stamp {stamp_s!r}: expected a finite time >= 0")
    for what, arr in (("position", position), ("velocity", velocity), ("effort", effort)):
        if arr and len(arr) != len(names):
            raise BusError(f"JointState {what}: {len(arr)} values for {len(names)} joints")
    sec = math.floor(stamp_s)
    nanosec = min(int(round((stamp_s - sec) * 1e9)), 999_999_999)
    w = _Cdr()
    w.int32(sec)        # builtin_interfaces/Time sec (int32: good until 2038, as ROS's own)
    w.uint32(nanosec)
    w.string(frame_id)
    w.strings(names)
    w.float64s(position)
    w.float64s(velocity)
    w.float64s(effort)
    return _CDR_LE + bytes(w.buf)


def attachment(seq: int, t_ns: int, gid: bytes) -> bytes:
    """rmw_zenoh's sample attachment: sequence number, source time (ns), GID (16 bytes), in Zenoh's own
    serialization (what rmw_zenoh_cpp writes with ``zenoh::ext::Serializer``)."""
    if len(gid) != 16:
        raise BusError(f"a ROS 2 GID has 16 bytes, not {len(gid)}")
    from zenoh import ext

    return ext.z_serialize((ext.Int64(seq), ext.Int64(t_ns), bytes(gid))).to_bytes()


class JointStatePublisher:
    """Puts each :class:`aioadept.bus.messages.RobotState` given to :meth:`publish` as a ROS 2 JointState on
    ``topic`` in ``domain_id``, through this process's Zenoh session (:func:`aioadept.bus.zenoh.session`, or
    ``session``). Not thread-safe: publish from one thread."""

    def __init__(self, topic: str = "/joint_states", *, domain_id: int = 0, session: Any = None,
                 frame_id: str = "") -> None:
        from aioadept.bus import zenoh as zb
        from aioadept.robots.viper_s850_urdf import JOINTS

        self.key = topic_key(topic, domain_id=domain_id)
        self.names = tuple(j.name for j in JOINTS)
        self.frame_id = frame_id
        self.gid = os.urandom(16)
        self.seq = 0
        self.published = 0
        s = session if session is not None else zb.session()
        try:
            self._pub = s.declare_publisher(self.key)
        except Exception as exc:
            raise BusError(f"cannot declare a Zenoh publisher on {self.key!r}: {exc}") from exc

    def publish(self, state: Any) -> None:
        """Put ``state`` (a RobotState: ``joints_deg``, ``wall_time_s``) as a JointState."""
        payload = encode_joint_state(state.wall_time_s, self.names, [math.radians(a) for a in state.joints_deg],
                                     frame_id=self.frame_id)
        self.seq += 1  # rmw_zenoh's publishers count from 1
        self._pub.put(payload, attachment=attachment(self.seq, time.time_ns(), self.gid))
        self.published += 1

    def close(self) -> None:
        pub, self._pub = self._pub, None
        if pub is not None:
            try:
                pub.undeclare()
            except Exception:
                pass
