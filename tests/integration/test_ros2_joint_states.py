"""``aioadept ros2`` (issue 23, item 5): the robot state on ROS 2's wire, checked by what a ROS 2 subscriber on
rmw_zenoh does with it: a Zenoh subscriber on the key rmw_zenoh_cpp declares for ``/<topic>`` of type
``sensor_msgs/msg/JointState`` (written out here from ROS 2's naming rule and rosbags' type hash, not from our module),
the payload decoded by rosbags (an independent ROS 2 message library), the attachment read as rmw_zenoh reads it.

Real processes on 127.0.0.1: ``aioadept sim`` (its state stream on ZeroMQ, or on Zenoh), ``aioadept ros2`` (a Zenoh
client of this test process, which is the router; multicast scouting off). No ROS 2 installation runs here: what
that leaves unchecked is said in docs/bus.md, "ROS 2".
"""

from __future__ import annotations

import asyncio
import importlib.util
import math
import struct
import subprocess
import sys
import time

import pytest

from aioadept.commands import MoveJoints, SetSpeed
from aioadept.testing.nodes import running_node

from bustransports import start_zenoh_router

pytestmark = [pytest.mark.skipif(importlib.util.find_spec("zenoh") is None,
                                 reason="the [zenoh] extra (eclipse-zenoh) is not installed"),
              pytest.mark.skipif(importlib.util.find_spec("rosbags") is None,
                                 reason="rosbags (the test extra) decodes the ROS 2 messages")]

TYPE = "sensor_msgs/msg/JointState"
TARGET = [30.0, -80.0, 170.0, 10.0, 60.0, -20.0]


def rmw_zenoh_key(domain: int, topic: str) -> str:
    from rosbags.typesys import Stores, get_typestore

    rihs = get_typestore(Stores.ROS2_JAZZY).hash_rihs01(TYPE)
    return f"{domain}/{topic.strip('/')}/sensor_msgs::msg::dds_::JointState_/{rihs}"


class RosListener:
    """What rmw_zenoh's subscription does with a sample: needs the attachment, decodes the CDR payload."""

    def __init__(self, key: str) -> None:
        import zenoh

        from aioadept.bus import zenoh as zb

        self.samples: list[tuple[int, int, bytes, object]] = []
        self.without_attachment = 0
        self._sub = zb.session().declare_subscriber(key, zenoh.handlers.Callback(self._on, indirect=True))

    def _on(self, sample) -> None:
        from rosbags.typesys import Stores, get_typestore

        att = sample.attachment
        if att is None:
            self.without_attachment += 1
            return
        a = att.to_bytes()
        seq, t_ns = struct.unpack_from("<qq", a)
        gid = a[17:] if len(a) == 33 and a[16] == 16 else b""
        msg = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(sample.payload.to_bytes(), TYPE)
        self.samples.append((seq, t_ns, gid, msg))

    async def wait_for(self, pred, timeout_s: float):
        t_end = time.monotonic() + timeout_s
        while time.monotonic() < t_end:
            for s in reversed(self.samples):
                if pred(s[3]):
                    return s
            await asyncio.sleep(0.02)
        raise AssertionError(f"no JointState matched in {timeout_s} s; {len(self.samples)} received")

    def close(self) -> None:
        self._sub.undeclare()


@pytest.mark.timeout(60)
@pytest.mark.parametrize("stream", ["zeromq", "zenoh"])
async def test_a_ros2_subscriber_on_rmw_zenohs_key_sees_the_arm_in_radians(tmp_path, stream) -> None:
    from aioadept.client import RobotClient

    router = start_zenoh_router()
    cell = f"ros{stream}"
    sim_args = ["--port", "0", "--state-rate", "50"]
    if stream == "zenoh":
        sim_args += ["--transport", "zenoh", "--zenoh-connect", router, "--cell", cell]
    else:
        sim_args += ["--state-endpoint", "tcp://127.0.0.1:0"]
    listener = RosListener(rmw_zenoh_key(3, f"/{cell}/joint_states"))
    try:
        async with running_node("sim", *sim_args, log_path=tmp_path / "sim.log") as sim:
            async with running_node("ros2", "--state-endpoint", sim.ready["state"], "--zenoh-connect", router,
                                    "--domain", "3", "--topic", f"/{cell}/joint_states",
                                    log_path=tmp_path / "ros2.log") as relay:
                assert relay.ready["ros2"] == rmw_zenoh_key(3, f"/{cell}/joint_states")
                async with RobotClient("127.0.0.1", int(sim.ready["port"])) as robot:
                    await robot.cmdexec(SetSpeed(100))
                    await robot.cmdexec(MoveJoints(TARGET))
                want = [math.radians(a) for a in TARGET]
                seq, t_ns, gid, msg = await listener.wait_for(
                    lambda m: max(abs(a - b) for a, b in zip(m.position, want)) < 1e-6, 10)
        assert msg.name == [f"joint_{i}" for i in range(1, 7)]
        assert list(msg.velocity) == [] and list(msg.effort) == []
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        assert abs(stamp - time.time()) < 30 and abs(t_ns * 1e-9 - time.time()) < 30
        assert listener.without_attachment == 0 and len(gid) == 16
        seqs = [s[0] for s in listener.samples]
        assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs) and seqs[0] >= 1
        assert len({s[2] for s in listener.samples}) == 1  # one publisher, one GID
        # The arm moved while we listened: earlier samples are elsewhere (not a constant stream of the target).
        assert any(max(abs(a - b) for a, b in zip(s[3].position, want)) > 0.1 for s in listener.samples)
    finally:
        listener.close()


@pytest.mark.timeout(30)
@pytest.mark.parametrize("argv, says", [
    (["--topic", "/joint states"], "ROS 2 topic '/joint states'"),
    (["--domain", "300"], "ROS 2 domain id 300"),
    (["--zenoh-listen", "tcp/127.0.0.1:7999", "--zenoh-connect", "tcp/127.0.0.1:7447"], "not both"),
    (["--zenoh-connect", "127.0.0.1:7447"], "Zenoh endpoint '127.0.0.1:7447'"),
])
def test_a_mistake_is_one_line_naming_it(argv, says) -> None:
    res = subprocess.run([sys.executable, "-m", "aioadept", "ros2", *argv], capture_output=True, text=True,
                         timeout=20)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("aioadept ros2: ") and says in lines[0], res.stderr
