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

It is also a node of the ROS 2 graph: rmw_zenoh builds its graph (``ros2 node list``, ``ros2 topic list -t``,
``ros2 topic info``, the type ``ros2 topic echo`` picks when none is given) from liveliness tokens under
``@ros2_lv/<domain>/``. :class:`JointStatePublisher` holds two while it runs, written as rmw_zenoh_cpp writes them
(its liveliness_utils.cpp): a node (``NN``) and its publisher (``MP``)::

    @ros2_lv/<domain>/<zid>/0/0/NN/%/<namespace>/<node name>
    @ros2_lv/<domain>/<zid>/0/1/MP/%/<namespace>/<node name>/<topic>/<DDS type>/<type hash>/1:2:1,1:,:,:,,

names with '/' as '%' (``/joint_states``: ``%joint_states``), ``<zid>`` the Zenoh session's id, the topic's type and
hash those of the data key, the QoS reliable, volatile, keep last 1 (:data:`JOINT_STATE_QOS`: what the publisher
does), each written out (rmw_zenoh leaves a default empty, but its default durability has changed). Checked against
rmw_zenoh's source and examples, not against a running ROS 2 (docs/bus.md, "ROS 2", says what was checked and how);
the attachment's GID is random, not rmw_zenoh's hash of the token.

Joint names are the URDF's of the robot model (:func:`aioadept.robots.urdf.urdf`: ``joint_1`` .. ``joint_6`` on a
Viper, ``joint_1`` .. ``joint_4`` on a Cobra), positions in ROS's units (:func:`joint_positions`: radians, metres for
a prismatic joint such as a Cobra's quill), stamped with the state's own ``wall_time_s``.
"""

from __future__ import annotations

import math
import os
import re
import struct
import time
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from aioadept.errors import BusError

__all__ = ["ADMIN_SPACE", "DEFAULT_NODE_NAME", "JOINT_STATE_DDS_TYPE", "JOINT_STATE_HASH", "JOINT_STATE_QOS",
           "RMW_ZENOH_DEFAULT_QOS", "Durability", "History", "JointStatePublisher", "Qos", "Reliability", "attachment",
           "check_namespace", "check_node_name", "encode_joint_state", "expand_topic_name", "joint_positions", "mangle",
           "node_token_key", "publisher_token_key", "topic_key", "zenoh_publisher_options"]

JOINT_STATE_DDS_TYPE = "sensor_msgs::msg::dds_::JointState_"
JOINT_STATE_HASH = "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
"""RIHS01 of ``sensor_msgs/msg/JointState`` (the same on Jazzy, Kilted and Rolling; tests/unit/test_ros2.py computes
it again with rosbags)."""

_ROS_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_CDR_LE = b"\x00\x01\x00\x00"  # encapsulation: plain CDR, little endian, no options


def _check_domain(domain_id: int) -> None:
    if not isinstance(domain_id, int) or isinstance(domain_id, bool) or not 0 <= domain_id <= 232:
        raise BusError(f"ROS 2 domain id {domain_id!r}: expected an integer 0..232")


def _topic_name(topic: str) -> str:
    """``topic`` without its outer "/" (``joint_states``), the one form both the data key and the publisher's
    token are written from; BusError for a name ROS would refuse."""
    name = topic.strip("/")
    if not all(_ROS_TOKEN.match(p) for p in name.split("/")):
        raise BusError(f"ROS 2 topic {topic!r}: expected a name like /joint_states (letters, digits, '_', "
                       f"separated by '/', each part not starting with a digit)")
    return name


def topic_key(topic: str, *, domain_id: int = 0, dds_type: str = JOINT_STATE_DDS_TYPE,
              type_hash: str = JOINT_STATE_HASH) -> str:
    """The key expression rmw_zenoh publishes ``topic`` (a ROS name, e.g. ``/joint_states``) on; BusError for a
    name ROS would refuse."""
    _check_domain(domain_id)
    return f"{domain_id}/{_topic_name(topic)}/{dds_type}/{type_hash}"


# -- The ROS 2 graph: rmw_zenoh's liveliness tokens -----------------------------------------------------------------
# Written as rmw_zenoh_cpp writes them (rmw_zenoh_cpp/src/detail/liveliness_utils.cpp: ADMIN_SPACE and the entity
# strings, the KeyexprIndex order, Entity::Entity, mangle_name, qos_to_keyexpr; qos.cpp: the defaults qos_to_keyexpr
# leaves out). A ROS 2 context subscribes to ``@ros2_lv/<domain>/**`` and builds its graph (node list, topic list,
# a topic's type) from the tokens alive under it.

ADMIN_SPACE = "@ros2_lv"
DEFAULT_NODE_NAME = "aioadept_ros2"
DEFAULT_ENCLAVE = "/"   # no SROS enclave: mangled "%", design.md's "just % if not set"


class Reliability(IntEnum):
    """``rmw_qos_reliability_policy_e`` (rmw/types.h): the number is what the token carries."""
    RELIABLE = 1
    BEST_EFFORT = 2


class Durability(IntEnum):
    """``rmw_qos_durability_policy_e``."""
    TRANSIENT_LOCAL = 1
    VOLATILE = 2


class History(IntEnum):
    """``rmw_qos_history_policy_e``."""
    KEEP_LAST = 1
    KEEP_ALL = 2


@dataclass(frozen=True, slots=True)
class Qos:
    """The QoS a token declares. Deadline, lifespan and liveliness are not fields: we offer none of them, so they
    stay at rmw_zenoh's defaults (infinite, infinite, automatic: a token's own liveliness), which the token leaves
    empty."""
    reliability: Reliability
    durability: Durability
    history: History
    depth: int

    def keyexpr(self, defaults: Qos | None = None) -> str:
        """rmw_zenoh's compact form (qos_to_keyexpr): ``<rel>:<dur>:<hist>,<depth>:<deadline s>,<ns>:<lifespan s>,
        <ns>:<liveliness>,<lease s>,<ns>``, rmw/types.h's numbers. rmw_zenoh leaves a value empty where it equals
        its own default (``defaults=RMW_ZENOH_DEFAULT_QOS`` does that); ``None`` writes every policy we declare."""

        def f(v: int, default: int | None) -> str:
            return "" if v == default else str(int(v))

        d = defaults
        return (f"{f(self.reliability, d and d.reliability)}:{f(self.durability, d and d.durability)}:"
                f"{f(self.history, d and d.history)},{f(self.depth, d and d.depth)}:,:,:,,")


RMW_ZENOH_DEFAULT_QOS = Qos(Reliability.RELIABLE, Durability.VOLATILE, History.KEEP_LAST, 42)
"""rmw_zenoh_cpp's QoS::default_qos() (qos.cpp): the values its tokens leave empty, and a reader fills in for an
empty field. Not fixed: before rmw_zenoh 0.5.0 (ros2/rmw_zenoh#521, backported to Jazzy) the durability was transient
local, so an empty durability means volatile to one reader and transient local to another. Our tokens therefore
write every policy they declare (:func:`publisher_token_key`)."""

JOINT_STATE_QOS = Qos(Reliability.RELIABLE, Durability.VOLATILE, History.KEEP_LAST, 1)
"""What :class:`JointStatePublisher` does, declared as such: a Zenoh publisher set as rmw_zenoh sets one for this QoS
(reliable, congestion control DROP: :func:`zenoh_publisher_options`), no cache for a late joiner (volatile), and
nothing kept but the sample being put (keep last 1; rmw_zenoh itself uses the depth only to size a transient-local
cache). docs/bus.md, "ROS 2", says why."""


def zenoh_publisher_options(qos: Qos) -> dict[str, str]:
    """The Zenoh publisher settings rmw_zenoh_cpp gives a publisher of ``qos`` (rmw_publisher_data.cpp,
    PublisherData::make): congestion control DROP, except BLOCK for reliable + keep all; reliability RELIABLE for a
    reliable one, Zenoh's default otherwise. Names of ``zenoh.CongestionControl`` / ``zenoh.Reliability`` members."""
    if qos.durability == Durability.TRANSIENT_LOCAL:
        raise BusError("a transient-local ROS 2 publisher needs a publication cache, which aioadept does not keep")
    opts = {"congestion_control": "DROP"}
    if qos.reliability == Reliability.RELIABLE:
        opts["reliability"] = "RELIABLE"
        if qos.history == History.KEEP_ALL:
            opts["congestion_control"] = "BLOCK"
    return opts


def check_node_name(name: str) -> str:
    """``name`` if ROS 2 accepts it as a node name (rmw_validate_node_name: letters, digits, '_', not starting with a
    digit, at most 255 characters); BusError otherwise."""
    if not isinstance(name, str) or not _ROS_TOKEN.match(name) or len(name) > 255:
        raise BusError(f"ROS 2 node name {name!r}: expected letters, digits and '_', not starting with a digit")
    return name


def check_namespace(namespace: str) -> str:
    """``namespace`` if ROS 2 accepts it as a node namespace (absolute: ``/`` or ``/a/b``, each part a ROS name
    token); BusError otherwise."""
    if not isinstance(namespace, str) or not namespace.startswith("/") or (
            namespace != "/" and not all(_ROS_TOKEN.match(p) for p in namespace[1:].split("/"))):
        raise BusError(f"ROS 2 namespace {namespace!r}: expected / or an absolute name like /cell1 (letters, "
                       f"digits, '_', separated by '/', each part not starting with a digit)")
    return namespace


def expand_topic_name(topic: str, *, node_name: str = DEFAULT_NODE_NAME, namespace: str = "/") -> str:
    """``topic`` fully qualified as ROS 2 expands a node's topic name (rcl_expand_topic_name; ROS 2 design, "Topic
    and Service name mapping to DDS"): ``/a/b`` stays; a relative ``a/b`` goes into the node's namespace
    (``/cell1/a/b``; ``/a/b`` in ``/``); a private ``~`` or ``~/a`` into the node's own (``/cell1/<node>/a``).
    Substitutions (``{node}``, ``{ns}``) are not taken. BusError for a name ROS would refuse."""
    check_node_name(node_name)
    check_namespace(namespace)
    ns = "" if namespace == "/" else namespace
    if isinstance(topic, str) and (topic == "~" or topic.startswith("~/")):
        full = f"{ns}/{node_name}{topic[1:]}"
    elif isinstance(topic, str) and not topic.startswith("/"):
        full = f"{ns}/{topic}"
    else:
        full = topic
    bad = BusError(f"ROS 2 topic {topic!r}: expected a name like joint_states, /joint_states or ~/joint_states "
                   f"(letters, digits, '_', separated by '/', each part not starting with a digit)")
    if not isinstance(full, str) or full.endswith("/") or "//" in full:
        raise bad
    try:
        _topic_name(full)  # the same check as the data key's, said with the name as given
    except BusError:
        raise bad from None
    return full


def mangle(name: str) -> str:
    """rmw_zenoh's mangle_name: every '/' becomes '%' (a token's chunk cannot hold '/', nor be empty)."""
    return name.replace("/", "%")


_ZID = re.compile(r"^[0-9a-f]{1,32}$")


def _entity_key(zid: str, kind: str, *, domain_id: int, node_id: int, entity_id: int, node_name: str,
                namespace: str, enclave: str) -> str:
    _check_domain(domain_id)
    if not isinstance(zid, str) or not _ZID.match(zid):
        raise BusError(f"Zenoh session id {zid!r}: expected its text form, 1-32 lowercase hex digits")
    for what, n in (("node id", node_id), ("entity id", entity_id)):
        if not isinstance(n, int) or isinstance(n, bool) or n < 0:
            raise BusError(f"rmw_zenoh {what} {n!r}: expected an integer >= 0")
    check_node_name(node_name)
    check_namespace(namespace)
    check_namespace(enclave)  # an enclave is written as a namespace is
    return "/".join((ADMIN_SPACE, str(domain_id), zid, str(node_id), str(entity_id), kind, mangle(enclave),
                     mangle(namespace), node_name))


def node_token_key(zid: str, *, domain_id: int = 0, node_id: int = 0, node_name: str = DEFAULT_NODE_NAME,
                   namespace: str = "/", enclave: str = DEFAULT_ENCLAVE) -> str:
    """The liveliness key rmw_zenoh_cpp declares for a node (``NN``):
    ``@ros2_lv/<domain>/<zid>/<node id>/<node id>/NN/<enclave>/<namespace>/<node name>``, names mangled.
    ``zid`` is the Zenoh session's id as text (``str(session.info.zid())``); no I/O. BusError for a bad part."""
    return _entity_key(zid, "NN", domain_id=domain_id, node_id=node_id, entity_id=node_id, node_name=node_name,
                       namespace=namespace, enclave=enclave)


def publisher_token_key(zid: str, topic: str, *, domain_id: int = 0, node_id: int = 0, entity_id: int = 1,
                        node_name: str = DEFAULT_NODE_NAME, namespace: str = "/", enclave: str = DEFAULT_ENCLAVE,
                        dds_type: str = JOINT_STATE_DDS_TYPE, type_hash: str = JOINT_STATE_HASH,
                        qos: Qos = JOINT_STATE_QOS, qos_defaults: Qos | None = None) -> str:
    """The liveliness key rmw_zenoh_cpp declares for a publisher (``MP``) of ``topic`` (fully qualified, as
    :func:`expand_topic_name` gives it and :func:`topic_key` takes it): the node's parts with its own entity id, then
    ``/<topic mangled>/<dds type>/<type hash>/<qos>``, the QoS as :meth:`Qos.keyexpr` writes it with
    ``qos_defaults`` (None: every policy written, read the same by every rmw_zenoh). No I/O; BusError for a bad
    part."""
    prefix = _entity_key(zid, "MP", domain_id=domain_id, node_id=node_id, entity_id=entity_id, node_name=node_name,
                         namespace=namespace, enclave=enclave)
    topic_part = mangle("/" + _topic_name(topic))
    return f"{prefix}/{topic_part}/{mangle(dds_type)}/{mangle(type_hash)}/{qos.keyexpr(qos_defaults)}"


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


def joint_positions(arm: Any, joints_deg: Sequence[float]) -> list[float]:
    """A JointState's positions of the robot model ``arm`` from V+ joint values: radians for a revolute joint, metres
    for a prismatic one (V+ degrees and mm). ``BusError`` when the count is not the arm's (another arm's stream)."""
    table = arm.urdf_joints
    if len(joints_deg) != len(table):
        raise BusError(f"robot.state has {len(joints_deg)} joints, the {arm.name} has {len(table)} "
                       f"(aioadept ros2 --robot-model)")
    return [v / 1000.0 if j.prismatic else math.radians(v) for j, v in zip(table, joints_deg, strict=True)]


class JointStatePublisher:
    """Puts each :class:`aioadept.bus.messages.RobotState` given to :meth:`publish` as a ROS 2 JointState on
    ``topic`` in ``domain_id``, through this process's Zenoh session (:func:`aioadept.bus.zenoh.session`, or
    ``session``), and holds the two liveliness tokens that make it a node of the ROS 2 graph (``node_name`` in
    ``namespace``, with one publisher: :attr:`node_token`, :attr:`publisher_token`) until :meth:`close`. ``arm``:
    the robot model whose joints the states are (default: the Viper s850). Not thread-safe: publish from one
    thread."""

    def __init__(self, topic: str = "joint_states", *, domain_id: int = 0, session: Any = None,
                 frame_id: str = "", node_name: str = DEFAULT_NODE_NAME, namespace: str = "/",
                 arm: Any = None) -> None:
        import zenoh

        from aioadept.bus import zenoh as zb
        from aioadept.robots import model

        # A relative or private name goes into the node's namespace, as a ROS 2 node's would.
        self.topic = topic = expand_topic_name(topic, node_name=node_name, namespace=namespace)
        self.key = topic_key(topic, domain_id=domain_id)
        self.arm = model() if arm is None else arm
        self.names = tuple(j.name for j in self.arm.urdf_joints)
        self.frame_id = frame_id
        self.gid = os.urandom(16)
        self.seq = 0
        self.published = 0
        s = session if session is not None else zb.session()
        zid = str(s.info.zid())
        # As rmw_zenoh_cpp counts them: one counter per context from 0, the node first, then its publisher.
        self.node_token = node_token_key(zid, domain_id=domain_id, node_id=0, node_name=node_name,
                                         namespace=namespace)
        self.publisher_token = publisher_token_key(zid, topic, domain_id=domain_id, node_id=0, entity_id=1,
                                                   node_name=node_name, namespace=namespace, qos=JOINT_STATE_QOS)
        want = zenoh_publisher_options(JOINT_STATE_QOS)
        opts = {"congestion_control": getattr(zenoh.CongestionControl, want["congestion_control"])}
        if "reliability" in want:
            opts["reliability"] = getattr(zenoh.Reliability, want["reliability"])
        self._pub = self._node_lv = self._pub_lv = None
        try:
            # rmw_zenoh's order: the node's token when the node is made, the publisher's after its publisher.
            self._node_lv = s.liveliness().declare_token(self.node_token)
            self._pub = s.declare_publisher(self.key, **opts)
            self._pub_lv = s.liveliness().declare_token(self.publisher_token)
        except Exception as exc:
            self.close()
            raise BusError(f"cannot declare the ROS 2 node and publisher of {self.key!r} on Zenoh: {exc}") from exc

    def publish(self, state: Any) -> None:
        """Put ``state`` (a RobotState: ``joints_deg``, ``wall_time_s``) as a JointState; ``BusError`` (nothing put)
        for a state with another number of joints than the arm's."""
        payload = encode_joint_state(state.wall_time_s, self.names, joint_positions(self.arm, state.joints_deg),
                                     frame_id=self.frame_id)
        self.seq += 1  # rmw_zenoh's publishers count from 1
        self._pub.put(payload, attachment=attachment(self.seq, time.time_ns(), self.gid))
        self.published += 1

    def close(self) -> None:
        """Leave the ROS 2 graph (the publisher's token, the publisher, then the node's token, the reverse of their
        declaration) and stop publishing. Idempotent."""
        for attr in ("_pub_lv", "_pub", "_node_lv"):
            entity = getattr(self, attr)
            setattr(self, attr, None)
            if entity is not None:
                try:
                    entity.undeclare()
                except Exception:  # a session already closed took it with it
                    pass
