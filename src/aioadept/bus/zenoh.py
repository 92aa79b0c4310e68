"""Eclipse Zenoh as the bus's second transport, behind the same API as ZeroMQ (the ``[zenoh]`` extra).

Where it sits: the socket layer (:mod:`aioadept.bus.sockets`) opens a
:class:`~aioadept.bus.zenohsocket.ZenohSocket` instead of a ZeroMQ
socket for an endpoint written ``zenoh:KEY`` (``zenoh:aioadept/<cell>/<node>/<topic>``), so publishers, subscribers,
the :class:`~aioadept.bus.Communicator` and the :class:`~aioadept.bus.Responder` run unchanged over either transport:
same frames, same Protobuf payloads, same request/response pairing (docs/bus.md, "Zenoh").

- A PUB puts on its key; ``send(payload)`` puts the payload alone (one frame), ``send_multipart([topic, payload])``
  puts the payload with the topic as the sample's attachment (two frames). A SUB subscribes to its key and filters
  on the first frame's prefixes exactly as a ZeroMQ SUB does.
- Requests and responses are publications on two keys (``.../vision/request``, ``.../vision/response``), or with
  ``Communicator(queries=True)`` Zenoh queries on the request key answered by their replies; a Responder answers
  both. The pairing contract (re-sending with the same id, the responder's answer cache, drop-oldest with an error
  answer, ``t_deadline``, the paper-style send()/recv()) is written once, above the transport, and keeps its tests
  on both (docs/bus.md, "Requests: publications or Zenoh queries").
- Zenoh calls back on a thread of its own: :mod:`aioadept.bus.zenohsocket` hands each message to the loop.
- One Zenoh session per process, opened on first use with :func:`configure`'s options: multicast scouting and
  gossip OFF, so nothing is discovered or announced beyond the endpoints written down (``tcp/127.0.0.1:PORT`` in
  the defaults and tests). A process either listens (``mode="router"``: it routes between the others) or connects
  to one that does (``mode="client"``).
- Presence: :func:`declare_node` declares a liveliness token ``aioadept/<cell>/<node>``;
  :class:`aioadept.bus.presence.NodeWatcher` reports each node appearing and vanishing.
"""

from __future__ import annotations

import json
import logging
import re
import threading
from dataclasses import dataclass
from typing import Any, Literal

from aioadept.errors import BusError

__all__ = [
    "DEFAULT_CELL",
    "DEFAULT_ROUTER",
    "PREFIX",
    "MODES",
    "ZenohOptions",
    "close_session",
    "configure",
    "announce_as",
    "announce_ready",
    "declare_node",
    "endpoint_for",
    "is_zenoh",
    "key_of",
    "node_key",
    "session",
]

log = logging.getLogger(__name__)

PREFIX = "zenoh:"
"""An endpoint starting with this is a Zenoh key expression (``zenoh:aioadept/demo/vision/request``)."""
ROOT = "aioadept"
DEFAULT_CELL = "demo"
DEFAULT_ROUTER = "tcp/127.0.0.1:7447"
"""Where a node connects and a router listens by default: loopback only (Zenoh's own default port)."""
MODES = ("router", "client", "peer")
PIN = "eclipse-zenoh==1.10.2"

_CHUNK = re.compile(r"^[A-Za-z0-9_.\-]+$")
_LOCATOR = re.compile(r"^(?:tcp|tls)/(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.\-]+):(?P<port>[0-9]{1,5})$")


def is_zenoh(endpoint: str | None) -> bool:
    """Whether ``endpoint`` (with or without a CZMQ ``@``/``>`` prefix) names a Zenoh key."""
    return isinstance(endpoint, str) and endpoint.strip().lstrip("@>").startswith(PREFIX)


def check_key(key: str, *, wildcards: bool = False) -> str:
    """``key`` if it is a key expression the bus uses (chunks of letters, digits, ``_ . -``; ``*``/``**`` only
    where ``wildcards``); raises :class:`BusError` naming it."""
    chunks = key.split("/")
    for c in chunks:
        if _CHUNK.match(c) or (wildcards and c in ("*", "**")):
            continue
        raise BusError(f"Zenoh key {key!r}: chunk {c!r} is not allowed; write chunks of letters, digits, '_', '.', "
                       f"'-' separated by '/', e.g. 'aioadept/demo/vision/request'")
    return key


def key_of(endpoint: str) -> str:
    """The key expression of a ``[@|>]zenoh:KEY`` endpoint (the prefix is meaningless for Zenoh and ignored)."""
    s = endpoint.strip().lstrip("@>")
    if not s.startswith(PREFIX):
        raise BusError(f"endpoint {endpoint!r} is not a Zenoh endpoint ({PREFIX}KEY)")
    return check_key(s[len(PREFIX):])


def node_key(cell: str, node: str, topic: str | None = None) -> str:
    """``aioadept/<cell>/<node>[/<topic>]``, each part checked."""
    key = f"{ROOT}/{cell}/{node}" + ("" if topic is None else f"/{topic}")
    return check_key(key)


def endpoint_for(cell: str, node: str, topic: str) -> str:
    """The bus endpoint of one stream: ``zenoh:aioadept/<cell>/<node>/<topic>``."""
    return PREFIX + node_key(cell, node, topic)


def check_locator(text: str) -> str:
    """``tcp/HOST:PORT`` (or ``tls/HOST:PORT``, with TLS set in a :attr:`ZenohOptions.config_file`) or raises
    :class:`BusError` (one line naming it)."""
    m = _LOCATOR.match(text.strip())
    if m is None or not 0 < int(m["port"]) <= 0xFFFF:
        raise BusError(f"Zenoh endpoint {text!r}: expected tcp/HOST:PORT (or tls/HOST:PORT) with a port 1..65535, "
                       f"e.g. {DEFAULT_ROUTER!r}")
    return text.strip()


def _zenoh() -> Any:
    try:
        import zenoh
    except ImportError as exc:
        raise BusError(f"the Zenoh transport needs the [zenoh] extra: pip install 'aioadept[zenoh]' ({PIN})") \
            from exc
    return zenoh


# ------------------------------------------------------------------------------------------------- the session


@dataclass(frozen=True, slots=True)
class ZenohOptions:
    """How this process's Zenoh session meets the others. ``mode="router"`` listens on ``listen`` and routes
    between the processes connected to it; ``"client"`` connects to ``connect`` (a router). Multicast scouting
    and gossip are always off: only the endpoints written here are ever used."""

    mode: Literal["router", "client", "peer"] = "client"
    connect: tuple[str, ...] = (DEFAULT_ROUTER,)
    listen: tuple[str, ...] = ()
    lowlatency: bool = True
    """Zenoh's low-latency unicast transport (no batching, no TX queue, no QoS priorities): request/response p50
    about half of the default's here. Every process of a cell must agree: a Zenoh router or peer of another kind
    (``zenohd``, ROS 2's rmw_zenoh) needs ``transport/unicast/lowlatency: true`` and ``qos/enabled: false``, or
    every aioadept process ``lowlatency=False``."""
    config_file: str | None = None
    """A Zenoh configuration file (JSON5, Zenoh's own format) for what these options do not say: who may connect
    (``transport/auth/usrpwd``), TLS (``transport/link/tls``, with ``tls/HOST:PORT`` endpoints), access control
    (``access_control``). Mode, endpoints, scouting and the low-latency setting are these options', set on top of
    the file's, so a file cannot turn multicast scouting or gossip back on (docs/security.md, "Zenoh")."""

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise BusError(f"Zenoh mode {self.mode!r}: expected one of {', '.join(MODES)}")
        for loc in (*self.connect, *self.listen):
            check_locator(loc)
        if self.mode == "router" and not self.listen:
            raise BusError("a Zenoh router needs a listen endpoint (tcp/127.0.0.1:PORT)")
        if self.mode == "client" and not self.connect:
            raise BusError("a Zenoh client needs a router to connect to (tcp/127.0.0.1:PORT)")
        if self.config_file is not None:
            self._file_config()  # a missing or malformed file is one line now, before anything starts

    @classmethod
    def router(cls, listen: str = DEFAULT_ROUTER, *, lowlatency: bool = True,
               config_file: str | None = None) -> ZenohOptions:
        return cls(mode="router", connect=(), listen=(listen,), lowlatency=lowlatency, config_file=config_file)

    @classmethod
    def client(cls, connect: str = DEFAULT_ROUTER, *, lowlatency: bool = True,
               config_file: str | None = None) -> ZenohOptions:
        return cls(mode="client", connect=(connect,), listen=(), lowlatency=lowlatency, config_file=config_file)

    def _file_config(self) -> Any:
        zenoh = _zenoh()
        try:
            return zenoh.Config.from_file(self.config_file)
        except Exception as exc:  # zenoh.ZError: no such file, not JSON5, a key Zenoh does not know
            reason = plain(exc)
            raise BusError(f"Zenoh config file {self.config_file}: {reason}") from None

    def config(self) -> Any:
        """The ``zenoh.Config``: :attr:`config_file`'s, if any, with these endpoints, no multicast scouting, no
        gossip."""
        zenoh = _zenoh()
        cfg = self._file_config() if self.config_file is not None else zenoh.Config()
        cfg.insert_json5("mode", json.dumps(self.mode))
        cfg.insert_json5("connect/endpoints", json.dumps(list(self.connect)))
        cfg.insert_json5("listen/endpoints", json.dumps(list(self.listen)))
        cfg.insert_json5("scouting/multicast/enabled", "false")
        cfg.insert_json5("scouting/gossip/enabled", "false")
        if self.lowlatency:
            cfg.insert_json5("transport/unicast/lowlatency", "true")
            cfg.insert_json5("transport/unicast/qos/enabled", "false")  # lowlatency requires it off
        if self.mode == "client":
            # Keep retrying a router that restarts instead of leaving the node deaf for the rest of its life.
            cfg.insert_json5("connect/timeout_ms", "5000")
        return cfg


_lock = threading.Lock()
_options = ZenohOptions()
_session: Any = None
_tokens: list[Any] = []


def configure(options: ZenohOptions) -> None:
    """Set how this process's session connects; before it is opened (else :class:`BusError` unless equal)."""
    global _options
    with _lock:
        if _session is not None and options != _options:
            raise BusError(f"the Zenoh session is already open with {_options}; configure() must come first")
        _options = options


def options() -> ZenohOptions:
    return _options


def session() -> Any:
    """This process's Zenoh session, opened on first use (raises :class:`BusError` when it cannot be)."""
    global _session
    with _lock:
        if _session is None:
            zenoh = _zenoh()
            # Zenoh's own log is off unless RUST_LOG asks for it: its lines (on stdout, in colour) would break the
            # one line a node writes for a failure (e.g. a router that refuses our credentials); what goes wrong
            # reaches the user as our BusError. RUST_LOG=zenoh=debug shows Zenoh's side (docs/troubleshooting.md).
            zenoh.init_log_from_env_or("off")
            try:
                _session = zenoh.open(_options.config())
            except Exception as exc:  # zenoh.ZError: e.g. a router that does not answer, a port in use
                raise BusError(session_error(exc, _options)) from exc
        return _session


_RUST_SOURCE = re.compile(r"\s*\bat /\S+?\.rs:\d+\.?")
"""Where in Zenoh's Rust source an error was raised (``at /root/.cargo/.../unicast.rs:338.``): nothing a user can
act on."""


def plain(exc: BaseException) -> str:
    """A Zenoh error's words on one line, without its Rust source locations."""
    return " ".join(_RUST_SOURCE.sub("", str(exc)).split())


def session_error(exc: BaseException, opts: ZenohOptions) -> str:
    """One line for a session that did not open: what failed, at which address, and the likely fix; Zenoh's own
    words (its Rust source locations removed) only for a failure not recognised here."""
    text = plain(exc)
    listen = ", ".join(opts.listen)
    connect = ", ".join(opts.connect)
    if "Address already in use" in text:
        why = (f"cannot listen on {listen}: the port is in use (another router or node runs there; `ss -ltnp` "
               f"shows which): stop it, or listen on a free port and connect the nodes there")
    elif "Cannot assign requested address" in text:
        why = (f"cannot listen on {listen}: this machine has no such address; listen on one of its own "
               f"(tcp/127.0.0.1:PORT for this machine only)")
    elif "Unable to connect" in text:
        why = (f"no router answers at {connect}, or it refused this node's credentials: start the cell's router "
               f"first (the starter, or a node with --zenoh-listen {opts.connect[0] if opts.connect else 'ADDR'}), "
               f"check --zenoh-config, or give the router's address with --zenoh-connect")
    else:
        return f"cannot open the Zenoh session ({opts.mode}, connect [{connect}], listen [{listen}]): {text}"
    return f"cannot open the Zenoh session: {why}"


def close_session() -> None:
    """Undeclare this process's node tokens and close its session (the next use opens a new one). Idempotent."""
    global _session
    with _lock:
        s, _session = _session, None
        tokens = list(_tokens)
        _tokens.clear()
    for t in tokens:
        try:
            t.undeclare()
        except Exception:
            pass
    if s is not None:
        try:
            s.close()
        except Exception as exc:
            log.debug("Zenoh session close: %r", exc)


_announce: tuple[str, str] | None = None


def announce_as(cell: str, node: str) -> None:
    """Have :func:`announce_ready` declare this process as node ``aioadept/<cell>/<node>`` (set by a node's
    ``--transport zenoh``; imports no Zenoh)."""
    global _announce
    _announce = (check_key(cell), check_key(node))


def announce_ready() -> None:
    """Declare the liveliness token set by :func:`announce_as`, if any: a node calls this as it prints READY, so
    a watcher sees it the moment it serves. Once: later calls (a V+ server opening its second port) do nothing. A
    no-op on ZeroMQ."""
    global _announce
    if _announce is not None:
        cell, node = _announce
        _announce = None
        declare_node(cell, node)


def declare_node(cell: str, node: str) -> Any:
    """Declare this process as node ``aioadept/<cell>/<node>`` (a liveliness token held until
    :func:`close_session` or the process ends); returns the token."""
    token = session().liveliness().declare_token(node_key(cell, node))
    with _lock:
        _tokens.append(token)
    return token
