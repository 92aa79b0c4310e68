"""``aioadept ros2``: the robot state on ROS 2's wire, checked by what a ROS 2 subscriber on
rmw_zenoh does with it: a Zenoh subscriber on the key rmw_zenoh_cpp declares for ``/<topic>`` of type
``sensor_msgs/msg/JointState`` (written out here from ROS 2's naming rule and rosbags' type hash, not from our module),
the payload decoded by rosbags (an independent ROS 2 message library), the attachment read as rmw_zenoh reads it;
and by what rmw_zenoh's graph cache does: a liveliness subscriber on ``@ros2_lv/**``, each token read by the port of
rmw_zenoh_cpp's own reader (tests/rmw_zenoh_port.py).

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
from rmw_zenoh_port import demangle_if_ros_type, entity_from_keyexpr

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
                    lambda m: max(abs(a - b) for a, b in zip(m.position, want, strict=True)) < 1e-6, 10)
        assert msg.name == [f"joint_{i}" for i in range(1, 7)]
        assert list(msg.velocity) == [] and list(msg.effort) == []
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        assert abs(stamp - time.time()) < 30 and abs(t_ns * 1e-9 - time.time()) < 30
        assert listener.without_attachment == 0 and len(gid) == 16
        seqs = [s[0] for s in listener.samples]
        assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs) and seqs[0] >= 1
        assert len({s[2] for s in listener.samples}) == 1  # one publisher, one GID
        # The arm moved while we listened: earlier samples are elsewhere (not a constant stream of the target).
        assert any(max(abs(a - b) for a, b in zip(s[3].position, want, strict=True)) > 0.1 for s in listener.samples)
    finally:
        listener.close()


class GraphWatcher:
    """What rmw_zenoh_cpp's graph cache listens to: a liveliness subscriber on the admin space (with the tokens
    already alive), each change recorded as (PUT | DELETE, key) in arrival order."""

    def __init__(self) -> None:
        import zenoh

        from aioadept.bus import zenoh as zb

        self.events: list[tuple[str, str]] = []
        self._sub = zb.session().liveliness().declare_subscriber(
            "@ros2_lv/**", zenoh.handlers.Callback(self._on, indirect=True), history=True)

    def _on(self, sample) -> None:
        import zenoh

        kind = "PUT" if sample.kind == zenoh.SampleKind.PUT else "DELETE"
        self.events.append((kind, str(sample.key_expr)))  # list.append: safe from Zenoh's thread

    def alive(self) -> set[str]:
        keys: set[str] = set()
        for kind, key in list(self.events):
            (keys.add if kind == "PUT" else keys.discard)(key)
        return keys

    async def until(self, pred, timeout_s: float, what: str):
        t_end = time.monotonic() + timeout_s
        while time.monotonic() < t_end:
            if pred():
                return
            await asyncio.sleep(0.02)
        raise AssertionError(f"{what} not seen in {timeout_s} s; liveliness events: {self.events}")

    def close(self) -> None:
        self._sub.undeclare()


class KeysSeen:
    """The key expressions JointState samples arrive on, under a domain (``<domain>/**``)."""

    def __init__(self, domain: int) -> None:
        import zenoh

        from aioadept.bus import zenoh as zb

        self.keys: set[str] = set()
        self._sub = zb.session().declare_subscriber(f"{domain}/**", zenoh.handlers.Callback(
            lambda sample: self.keys.add(str(sample.key_expr)), indirect=True))

    def close(self) -> None:
        self._sub.undeclare()


@pytest.mark.timeout(60)
async def test_the_ros2_graph_sees_the_node_and_its_publisher_while_it_runs(tmp_path) -> None:
    router = start_zenoh_router()
    graph = GraphWatcher()
    data = KeysSeen(5)
    try:
        async with running_node("sim", "--port", "0", "--state-rate", "50", "--state-endpoint", "tcp://127.0.0.1:0",
                                log_path=tmp_path / "sim.log") as sim:
            async with running_node("ros2", "--state-endpoint", sim.ready["state"], "--zenoh-connect", router,
                                    "--domain", "5", "--topic", "/lv/joint_states", "--node-name", "viper_state",
                                    "--namespace", "/cell_a", log_path=tmp_path / "ros2.log") as relay:
                assert relay.ready["node"] == "/cell_a/viper_state"
                await graph.until(lambda: len(graph.alive()) == 2 and data.keys, 10, "two tokens and a sample")
                entities = sorted((entity_from_keyexpr(k) for k in graph.alive()), key=lambda e: e.kind)
                alive = set(graph.alive())
        # SIGINT, clean exit (running_node checks the code): both tokens are gone, the publisher's first, as
        # rmw_zenoh_cpp destroys a node's publisher before the node.
        await graph.until(lambda: not graph.alive(), 10, "both tokens gone")
        deletes = [k for kind, k in graph.events if kind == "DELETE"]
        node, pub = entities
        assert (node.kind, pub.kind) == ("node", "publisher")
        assert deletes == [k for k in sorted(alive, key=lambda k: "/NN/" in k)]  # MP, then NN
        assert (node.domain_id, node.namespace, node.node_name, node.enclave) == (5, "/cell_a", "viper_state", "/")
        assert (pub.domain_id, pub.namespace, pub.node_name) == (5, "/cell_a", "viper_state")
        assert pub.zid == node.zid and pub.nid == node.id == node.nid and pub.id != node.id
        # The publisher's token names what arrives: its topic/type/hash are the key the samples came on, the type
        # is the one `ros2 topic echo` would pick (rosbags computes the hash independently).
        t = pub.topic_info
        assert data.keys == {t.topic_keyexpr} == {rmw_zenoh_key(5, "/lv/joint_states")}
        assert t.name == "/lv/joint_states" and demangle_if_ros_type(t.type) == TYPE
        assert (t.qos["reliability"], t.qos["durability"], t.qos["history"], t.qos["depth"]) == \
            ("reliable", "volatile", "keep_last", 1)
    finally:
        graph.close()
        data.close()


@pytest.mark.timeout(30)
@pytest.mark.parametrize("argv, says", [
    (["--topic", "/joint states"], "ROS 2 topic '/joint states'"),
    (["--domain", "300"], "ROS 2 domain id 300"),
    (["--node-name", "2nd"], "ROS 2 node name '2nd'"),
    (["--namespace", "cell1"], "ROS 2 namespace 'cell1'"),
    (["--zenoh-listen", "tcp/127.0.0.1:7999", "--zenoh-connect", "tcp/127.0.0.1:7447"], "not both"),
    (["--zenoh-connect", "127.0.0.1:7447"], "Zenoh endpoint '127.0.0.1:7447'"),
])
def test_a_mistake_is_one_line_naming_it(argv, says) -> None:
    res = subprocess.run([sys.executable, "-m", "aioadept", "ros2", *argv], capture_output=True, text=True,
                         timeout=20)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("aioadept ros2: ") and says in lines[0], res.stderr
