"""A port, for tests, of how rmw_zenoh_cpp reads a graph liveliness token: ``liveliness::Entity::make(const
std::string & keyexpr)`` and ``keyexpr_to_qos`` (rmw_zenoh_cpp/src/detail/liveliness_utils.cpp, as in
ros2/rmw_zenoh 3411fdec and the ros2-gbp release copy 091acf7b, which agree), the defaults it fills in
(qos.cpp, ``QoS::QoS``), and ``_demangle_if_ros_type`` (graph_cache.cpp), which turns the token's DDS type into
the name ``ros2 topic list -t`` prints and ``ros2 topic echo`` subscribes with.

It is written from their source, rule by rule, and not from aioadept.bus.ros2, so a key our builders write is checked
against the reader a ROS 2 node would run. Where the C++ is lenient (``std::stoul`` on the domain, parts beyond the
13th ignored) the port is as lenient; what the C++ would refuse, this raises :class:`TokenRefused` for.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

ADMIN_SPACE = "@ros2_lv"
# enum KeyexprIndex
ADMIN, DOMAIN, ZID, NID, ID, ENTITY, ENCLAVE, NAMESPACE, NODE_NAME, TOPIC_NAME, TOPIC_TYPE, TOPIC_HASH, TOPIC_QOS = \
    range(13)
KEYEXPR_INDEX_MIN, KEYEXPR_INDEX_MAX = NODE_NAME, TOPIC_QOS
STR_TO_ENTITY = {"NN": "node", "MP": "publisher", "MS": "subscription", "SS": "service", "SC": "client"}

# rmw/types.h enums, as the str_to_qos_* maps list them (reliability/durability: SYSTEM_DEFAULT, RELIABLE |
# TRANSIENT_LOCAL, BEST_EFFORT | VOLATILE, UNKNOWN; history: SYSTEM_DEFAULT, KEEP_LAST, KEEP_ALL, UNKNOWN;
# liveliness: SYSTEM_DEFAULT, AUTOMATIC, MANUAL_BY_TOPIC = 3, UNKNOWN, BEST_AVAILABLE)
STR_TO_RELIABILITY = {"0": "system_default", "1": "reliable", "2": "best_effort", "3": "unknown"}
STR_TO_DURABILITY = {"0": "system_default", "1": "transient_local", "2": "volatile", "3": "unknown"}
STR_TO_HISTORY = {"0": "system_default", "1": "keep_last", "2": "keep_all", "3": "unknown"}
STR_TO_LIVELINESS = {"0": "system_default", "1": "automatic", "3": "manual_by_topic", "4": "unknown",
                     "5": "best_available"}
INFINITE = (9223372036, 854775807)  # RMW_DURATION_INFINITE (sec, nsec)
# qos.cpp, QoS::QoS: RMW_ZENOH_DEFAULT_*
DEFAULT_QOS = dict(reliability="reliable", durability="volatile", history="keep_last", depth=42, deadline=INFINITE,
                   lifespan=INFINITE, liveliness="automatic", liveliness_lease_duration=INFINITE)
# ... and before rmw_zenoh 0.5.0: transient local ("Switch default durability to volatile", ros2/rmw_zenoh#521,
# backported to jazzy; issue #485 tabulates the old defaults). A token is read with its reader's defaults.
DEFAULT_QOS_BEFORE_0_5 = dict(DEFAULT_QOS, durability="transient_local")


class TokenRefused(ValueError):
    """Where rmw_zenoh_cpp logs "Received invalid liveliness token..." and returns nullptr / std::nullopt."""


@dataclass(frozen=True)
class TopicInfo:
    name: str
    type: str
    type_hash: str
    qos: dict
    topic_keyexpr: str  # TopicInfo's constructor: <domain>/<name without outer '/'>/<type>/<hash>


@dataclass(frozen=True)
class Entity:
    kind: str
    domain_id: int
    zid: str
    nid: str
    id: str
    enclave: str
    namespace: str
    node_name: str
    topic_info: TopicInfo | None


def demangle_name(s: str) -> str:
    return s.replace("%", "/")


def _split(s: str, delim: str) -> list[str]:
    return s.split(delim)  # split_keyexpr keeps empty pieces, as str.split does


def _stoul(s: str) -> int:
    # std::stoul: leading whitespace, an optional sign, digits, anything after ignored; none at all throws.
    m = re.match(r"\s*([+-]?\d+)", s)
    if not m:
        raise TokenRefused(f"std::stoul({s!r}) throws")
    return int(m.group(1))


def _str_to_size_t(s: str, default):
    if s == "":
        return default
    if not re.fullmatch(r"\s*[+-]?\d+", s):  # strtoul must consume the whole string
        raise TokenRefused(f"not a number: {s!r}")
    return int(s)


def keyexpr_to_qos(keyexpr: str, defaults: dict = DEFAULT_QOS) -> dict:
    parts = _split(keyexpr, ":")
    if len(parts) < 6:
        raise TokenRefused(f"QoS {keyexpr!r}: {len(parts)} ':' parts, 6 needed")
    history, deadline, lifespan, liveliness = (_split(parts[i], ",") for i in (2, 3, 4, 5))
    if len(history) < 2 or len(deadline) < 2 or len(lifespan) < 2 or len(liveliness) < 3:
        raise TokenRefused(f"QoS {keyexpr!r}: a ',' group is short")
    d = defaults
    try:
        qos = dict(
            history=d["history"] if history[0] == "" else STR_TO_HISTORY[history[0]],
            reliability=d["reliability"] if parts[0] == "" else STR_TO_RELIABILITY[parts[0]],
            durability=d["durability"] if parts[1] == "" else STR_TO_DURABILITY[parts[1]],
            liveliness=d["liveliness"] if liveliness[0] == "" else STR_TO_LIVELINESS[liveliness[0]])
    except KeyError as exc:
        raise TokenRefused(f"QoS {keyexpr!r}: unknown policy value {exc}") from None
    qos["depth"] = _str_to_size_t(history[1], d["depth"])
    qos["deadline"] = (_str_to_size_t(deadline[0], d["deadline"][0]), _str_to_size_t(deadline[1], d["deadline"][1]))
    qos["lifespan"] = (_str_to_size_t(lifespan[0], d["lifespan"][0]), _str_to_size_t(lifespan[1], d["lifespan"][1]))
    qos["liveliness_lease_duration"] = (_str_to_size_t(liveliness[1], d["liveliness_lease_duration"][0]),
                                        _str_to_size_t(liveliness[2], d["liveliness_lease_duration"][1]))
    return qos


def _strip_slashes(s: str) -> str:
    start, end = (1 if s[:1] == "/" else 0), (len(s) - 1 if s[-1:] == "/" else len(s))
    return s[start:end]


def entity_from_keyexpr(keyexpr: str, qos_defaults: dict = DEFAULT_QOS) -> Entity:
    """Entity::make(const std::string & keyexpr), by a reader whose QoS::default_qos() is ``qos_defaults``."""
    parts = _split(keyexpr, "/")
    if len(parts) < KEYEXPR_INDEX_MIN + 1:
        raise TokenRefused(f"{len(parts)}/{KEYEXPR_INDEX_MIN + 1} parts: {keyexpr}")
    if any(p == "" for p in parts):
        raise TokenRefused(f"empty parts: {keyexpr}")
    if parts[ADMIN] != ADMIN_SPACE:
        raise TokenRefused("invalid admin space")
    kind = STR_TO_ENTITY.get(parts[ENTITY])
    if kind is None:
        raise TokenRefused(f"invalid entity {parts[ENTITY]}")
    domain_id = _stoul(parts[DOMAIN])
    topic_info = None
    if kind != "node":
        if len(parts) < KEYEXPR_INDEX_MAX + 1:
            raise TokenRefused("non-node entity without required parameters")
        name = demangle_name(parts[TOPIC_NAME])
        type_ = demangle_name(parts[TOPIC_TYPE])
        type_hash = demangle_name(parts[TOPIC_HASH])
        topic_info = TopicInfo(name, type_, type_hash, keyexpr_to_qos(parts[TOPIC_QOS], qos_defaults),
                               f"{domain_id}/{_strip_slashes(name)}/{type_}/{type_hash}")
    return Entity(kind, domain_id, parts[ZID], parts[NID], parts[ID], demangle_name(parts[ENCLAVE]),
                  demangle_name(parts[NAMESPACE]), demangle_name(parts[NODE_NAME]), topic_info)


def demangle_if_ros_type(dds_type: str) -> str:
    """graph_cache.cpp's _demangle_if_ros_type: ``pkg::msg::dds_::Name_`` -> ``pkg/msg/Name``."""
    if dds_type[-1] != "_":
        return dds_type
    pos = dds_type.find("dds_::")
    if pos < 0:
        return dds_type
    start = pos + len("dds_::")
    return dds_type[:pos].replace("::", "/") + dds_type[start:len(dds_type) - 1]
