"""aioadept.bus.ros2 against an independent ROS 2 message library (rosbags): the JointState CDR is byte for byte
what rosbags writes and reads back to the same values, the type hash is the one rosbags computes, and the attachment
has the layout rmw_zenoh_cpp reads (sequence, time, GID: 33 bytes). The graph's liveliness tokens against
rmw_zenoh's own examples and a port of its own token reader."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import rmw_zenoh_port as rz  # tests/: rmw_zenoh_cpp's token reader, ported

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


# -- The graph's liveliness tokens ---------------------------------------------------------------------------------
# Expected keys are rmw_zenoh's own: docs/design.md ("Graph Cache", the demo_nodes_cpp examples, verbatim), read
# back by a port of rmw_zenoh_cpp's own token reader (tests/rmw_zenoh_port.py: Entity::make, keyexpr_to_qos).

STRING_DDS = "std_msgs::msg::dds_::String_"
STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
# rmw_zenoh docs/design.md, "Graph Cache": `listener` node; `talker` node's publisher on `chatter` (domain 2 there)
DESIGN_NN = "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
DESIGN_MP = ("@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/"
             "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18/::,7:,:,:,,")
ZID = "5f4b4dee87ce5c030a636149a4ff2de5"


def test_the_design_docs_node_token() -> None:
    assert ros2.node_token_key("aac3178e146ba6f1fc6e6a4085e77f21", node_name="listener") == DESIGN_NN


def test_the_design_docs_publisher_token() -> None:
    # demo_nodes_cpp's talker: QoS depth 7, reliable, volatile (rclcpp's defaults, made explicit by rmw_zenoh's
    # best_available_qos); its publisher is the context's entity 10.
    talker_qos = ros2.Qos(ros2.Reliability.RELIABLE, ros2.Durability.VOLATILE, ros2.History.KEEP_LAST, 7)
    key = ros2.publisher_token_key("8b20917502ee955ac4476e0266340d5c", "/chatter", domain_id=2, node_id=0,
                                   entity_id=10, node_name="talker", dds_type=STRING_DDS, type_hash=STRING_HASH,
                                   qos=talker_qos, qos_defaults=ros2.RMW_ZENOH_DEFAULT_QOS)
    assert key == DESIGN_MP


def test_the_port_reads_the_design_docs_examples() -> None:
    # the port itself, against what rmw_zenoh says its examples mean
    nn = rz.entity_from_keyexpr(DESIGN_NN)
    assert (nn.kind, nn.domain_id, nn.zid, nn.nid, nn.id) == ("node", 0, "aac3178e146ba6f1fc6e6a4085e77f21", "0", "0")
    assert (nn.enclave, nn.namespace, nn.node_name, nn.topic_info) == ("/", "/", "listener", None)
    mp = rz.entity_from_keyexpr(DESIGN_MP)
    assert (mp.kind, mp.domain_id, mp.nid, mp.id, mp.node_name) == ("publisher", 2, "0", "10", "talker")
    t = mp.topic_info
    assert (t.name, t.type, t.type_hash) == ("/chatter", STRING_DDS, STRING_HASH)
    assert t.topic_keyexpr == f"2/chatter/{STRING_DDS}/{STRING_HASH}"
    assert t.qos == dict(rz.DEFAULT_QOS, depth=7)
    assert rz.demangle_if_ros_type(t.type) == "std_msgs/msg/String"


@pytest.mark.parametrize("domain, ns, node, topic", [
    (0, "/", "aioadept_ros2", "/joint_states"),
    (7, "/cell1", "viper", "/cell1/r1/joint_states"),
    (232, "/a/b_2", "_n", "joint_states"),   # a topic without its leading '/' is taken as fully qualified
])
def test_our_tokens_read_back_through_rmw_zenohs_reader(domain, ns, node, topic) -> None:
    nn = rz.entity_from_keyexpr(ros2.node_token_key(ZID, domain_id=domain, node_name=node, namespace=ns))
    assert (nn.kind, nn.domain_id, nn.zid, nn.nid, nn.id) == ("node", domain, ZID, "0", "0")
    assert (nn.enclave, nn.namespace, nn.node_name) == ("/", ns, node)
    mp = rz.entity_from_keyexpr(ros2.publisher_token_key(ZID, topic, domain_id=domain, node_name=node,
                                                         namespace=ns))
    assert (mp.kind, mp.domain_id, mp.zid, mp.nid, mp.id) == ("publisher", domain, ZID, "0", "1")
    assert (mp.enclave, mp.namespace, mp.node_name) == ("/", ns, node)
    t = mp.topic_info
    assert t.name == "/" + topic.strip("/")
    assert rz.demangle_if_ros_type(t.type) == "sensor_msgs/msg/JointState"
    assert t.type_hash == ros2.JOINT_STATE_HASH
    # the topic the graph announces is the key the samples are put on
    assert t.topic_keyexpr == ros2.topic_key(topic, domain_id=domain)
    ours = {"reliability": "reliable", "durability": "volatile", "history": "keep_last", "depth": 1}
    assert t.qos == dict(rz.DEFAULT_QOS, **ours)  # the rest rmw_zenoh's defaults
    # ... and the same for a reader from before rmw_zenoh's default durability became volatile
    old = rz.entity_from_keyexpr(ros2.publisher_token_key(ZID, topic, domain_id=domain, node_name=node,
                                                          namespace=ns), qos_defaults=rz.DEFAULT_QOS_BEFORE_0_5)
    assert {k: old.topic_info.qos[k] for k in ours} == ours


@pytest.mark.parametrize("qos, defaults, text, read", [
    (ros2.RMW_ZENOH_DEFAULT_QOS, ros2.RMW_ZENOH_DEFAULT_QOS, "::,:,:,:,,", {}),
    (ros2.JOINT_STATE_QOS, ros2.RMW_ZENOH_DEFAULT_QOS, "::,1:,:,:,,", {"depth": 1}),
    (ros2.JOINT_STATE_QOS, None, "1:2:1,1:,:,:,,", {"depth": 1}),   # what our token writes
    # the policies' numbers are rmw/types.h's (the old token comment's "2:1:2,10": best effort, transient local,
    # keep all, depth 10)
    (ros2.Qos(ros2.Reliability.BEST_EFFORT, ros2.Durability.TRANSIENT_LOCAL, ros2.History.KEEP_ALL, 10),
     ros2.RMW_ZENOH_DEFAULT_QOS, "2:1:2,10:,:,:,,",
     {"reliability": "best_effort", "durability": "transient_local", "history": "keep_all", "depth": 10}),
])
def test_qos_text_is_rmw_zenohs(qos, defaults, text, read) -> None:
    assert qos.keyexpr(defaults) == text
    assert rz.keyexpr_to_qos(text) == dict(rz.DEFAULT_QOS, **read)


def test_our_qos_text_means_the_same_to_an_older_reader() -> None:
    # an empty durability is transient local to rmw_zenoh < 0.5.0: the reason our token writes every policy
    assert rz.keyexpr_to_qos("::,1:,:,:,,", rz.DEFAULT_QOS_BEFORE_0_5)["durability"] == "transient_local"
    assert rz.keyexpr_to_qos(ros2.JOINT_STATE_QOS.keyexpr(), rz.DEFAULT_QOS_BEFORE_0_5)["durability"] == "volatile"


def test_the_zenoh_publisher_is_set_as_rmw_zenoh_sets_one_for_our_qos() -> None:
    assert ros2.zenoh_publisher_options(ros2.JOINT_STATE_QOS) == {"congestion_control": "DROP",
                                                                  "reliability": "RELIABLE"}
    keep_all = ros2.Qos(ros2.Reliability.RELIABLE, ros2.Durability.VOLATILE, ros2.History.KEEP_ALL, 1)
    assert ros2.zenoh_publisher_options(keep_all)["congestion_control"] == "BLOCK"
    best_effort = ros2.Qos(ros2.Reliability.BEST_EFFORT, ros2.Durability.VOLATILE, ros2.History.KEEP_ALL, 1)
    assert ros2.zenoh_publisher_options(best_effort) == {"congestion_control": "DROP"}
    with pytest.raises(BusError, match="cache"):
        ros2.zenoh_publisher_options(ros2.Qos(ros2.Reliability.RELIABLE, ros2.Durability.TRANSIENT_LOCAL,
                                              ros2.History.KEEP_LAST, 1))


@pytest.mark.parametrize("kw, says", [
    ({"node_name": "2d"}, "node name"), ({"node_name": "a/b"}, "node name"), ({"node_name": ""}, "node name"),
    ({"node_name": "a" * 256}, "node name"), ({"namespace": "cell1"}, "namespace"),
    ({"namespace": "/cell1/"}, "namespace"), ({"namespace": "//x"}, "namespace"), ({"namespace": "/1x"}, "namespace"),
    ({"domain_id": 233}, "domain"), ({"node_id": -1}, "node id"), ({"zid": "ABC"}, "session id"),
    ({"zid": ""}, "session id"),
])
def test_bad_token_parts_are_refused(kw, says) -> None:
    zid = kw.pop("zid", ZID)
    with pytest.raises(BusError, match=says):
        ros2.node_token_key(zid, **kw)


def test_a_bad_topic_is_refused_in_the_token_too() -> None:
    with pytest.raises(BusError, match="ROS 2 topic"):
        ros2.publisher_token_key(ZID, "/joint states")
    with pytest.raises(BusError, match="entity id"):
        ros2.publisher_token_key(ZID, "/joint_states", entity_id=True)


class _FakeSession:
    """Records what JointStatePublisher declares on a Zenoh session, in order (no sockets)."""

    def __init__(self, zid: str, fail_publisher: bool = False) -> None:
        self.zid, self.fail_publisher, self.log = zid, fail_publisher, []
        self.info = type("Info", (), {"zid": lambda _self: zid})()

    def liveliness(self):
        return self

    def declare_token(self, key):
        self.log.append(("token", key))
        return _Undeclarable(self.log, ("untoken", key))

    def declare_publisher(self, key, **opts):
        if self.fail_publisher:
            raise RuntimeError("refused")
        self.log.append(("publisher", key, opts))
        return _Undeclarable(self.log, ("unpublisher", key))


class _Undeclarable:
    def __init__(self, log, entry) -> None:
        self.log, self.entry = log, entry

    def undeclare(self) -> None:
        self.log.append(self.entry)


def test_the_publisher_declares_node_then_publisher_and_undeclares_in_reverse() -> None:
    s = _FakeSession(ZID)
    pub = ros2.JointStatePublisher("/joint_states", domain_id=4, session=s, node_name="viper", namespace="/c1")
    nn = ros2.node_token_key(ZID, domain_id=4, node_name="viper", namespace="/c1")
    mp = ros2.publisher_token_key(ZID, "/joint_states", domain_id=4, node_name="viper", namespace="/c1")
    assert (pub.node_token, pub.publisher_token) == (nn, mp)
    opts = {"congestion_control": zenoh.CongestionControl.DROP, "reliability": zenoh.Reliability.RELIABLE}
    assert s.log == [("token", nn), ("publisher", pub.key, opts), ("token", mp)]
    pub.close()
    pub.close()  # idempotent
    assert s.log[3:] == [("untoken", mp), ("unpublisher", pub.key), ("untoken", nn)]


def test_a_publisher_that_cannot_be_declared_leaves_no_token() -> None:
    s = _FakeSession(ZID, fail_publisher=True)
    with pytest.raises(BusError, match="cannot declare"):
        ros2.JointStatePublisher("/joint_states", session=s)
    nn = ros2.node_token_key(ZID)
    assert s.log == [("token", nn), ("untoken", nn)]


@pytest.mark.parametrize("topic, ns, full", [
    ("/joint_states", "/", "/joint_states"), ("/joint_states", "/cell1", "/joint_states"),  # absolute: as given
    ("joint_states", "/", "/joint_states"), ("joint_states", "/cell1", "/cell1/joint_states"),  # relative
    ("arm/joint_states", "/a/b", "/a/b/arm/joint_states"),
    ("~/joint_states", "/cell1", "/cell1/viper/joint_states"), ("~", "/", "/viper"),  # private
])
def test_a_topic_name_is_expanded_as_a_ros_2_node_expands_it(topic, ns, full) -> None:
    # rcl_expand_topic_name's rules: robot_state_publisher in namespace /cell1 listens on joint_states, i.e.
    # /cell1/joint_states, so a relay in the same namespace must publish there with the same relative name.
    assert ros2.expand_topic_name(topic, node_name="viper", namespace=ns) == full


@pytest.mark.parametrize("topic", ["", "/", "joint states", "a//b", "a/", "~x", "1abc", "{node}/js", "/a/2b"])
def test_a_topic_name_ros_would_refuse_is_refused_before_expansion_hides_it(topic) -> None:
    with pytest.raises(BusError, match="ROS 2 topic") as err:
        ros2.expand_topic_name(topic, node_name="viper", namespace="/cell1")
    assert f"ROS 2 topic {topic!r}:" in str(err.value), "the name as the user gave it, not its expansion"


def test_a_relative_topic_goes_into_the_nodes_namespace_on_the_wire_and_in_its_token() -> None:
    s = _FakeSession(ZID)
    pub = ros2.JointStatePublisher("joint_states", domain_id=2, session=s, node_name="viper", namespace="/c1")
    assert pub.topic == "/c1/joint_states"
    assert pub.key == ros2.topic_key("/c1/joint_states", domain_id=2)
    assert pub.key.startswith("2/c1/joint_states/")
    assert pub.publisher_token == ros2.publisher_token_key(ZID, "/c1/joint_states", domain_id=2, node_name="viper",
                                                           namespace="/c1")
    assert "/%c1%joint_states/" in pub.publisher_token
    pub.close()


class _Putter(_Undeclarable):
    def put(self, payload, attachment=None) -> None:
        self.log.append(("put", bytes(payload)))


class _PutSession(_FakeSession):
    def declare_publisher(self, key, **opts):
        self.log.append(("publisher", key, opts))
        return _Putter(self.log, ("unpublisher", key))


def test_a_cobras_joint_states_are_its_four_joints_in_ros_units(store) -> None:
    from aioadept.bus.messages import RobotState
    from aioadept.robots import model

    cobra = model("cobra-s600")
    s = _PutSession(ZID)
    pub = ros2.JointStatePublisher("/joint_states", session=s, arm=cobra)
    q = (20.0, 60.0, 120.0, -30.0)
    pub.publish(RobotState(t_s=1.0, wall_time_s=1764270000.5, joints_deg=q, pose=cobra.forward(q)))
    msg = store.deserialize_cdr([e for e in s.log if e[0] == "put"][0][1], TYPE)
    assert list(msg.name) == ["joint_1", "joint_2", "joint_3", "joint_4"]
    # revolute joints in radians, the quill (prismatic) in metres
    assert list(msg.position) == pytest.approx([math.radians(20.0), math.radians(60.0), 0.12, math.radians(-30.0)])
    viper_q = (0.0, -90.0, 180.0, 0.0, 90.0, 0.0)
    with pytest.raises(BusError, match="has 6 joints, the cobra-s600 has 4"):
        pub.publish(RobotState(t_s=2.0, wall_time_s=2.0, joints_deg=viper_q, pose=cobra.forward(q)))
    assert pub.published == 1
    pub.close()


def test_aioadept_ros2_takes_the_robot_model_by_name(capsys) -> None:
    from aioadept.cli.ros2 import build_parser

    assert build_parser().parse_args(["--robot-model", "cobra-s800"]).robot_model == "cobra-s800"
    assert build_parser().parse_args([]).robot_model == "viper-s850"
    with pytest.raises(SystemExit) as info:
        build_parser().parse_args(["--robot-model", "cobra-s1000"])
    assert info.value.code == 2 and "cobra-s600" in capsys.readouterr().err.strip().splitlines()[-1]
