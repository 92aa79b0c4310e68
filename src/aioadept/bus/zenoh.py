"""Eclipse Zenoh as the bus's second transport, behind the same API as ZeroMQ (the ``[zenoh]`` extra).

Where it sits: the socket layer (:mod:`aioadept.bus.sockets`) opens a :class:`ZenohSocket` instead of a ZeroMQ
socket for an endpoint written ``zenoh:KEY`` (``zenoh:aioadept/<cell>/<node>/<topic>``), so publishers, subscribers,
the :class:`~aioadept.bus.Communicator` and the :class:`~aioadept.bus.Responder` run unchanged over either transport:
same frames, same Protobuf payloads, same request/response pairing (docs/bus.md, "Zenoh").

- A PUB puts on its key; ``send(payload)`` puts the payload alone (one frame), ``send_multipart([topic, payload])``
  puts the payload with the topic as the sample's attachment (two frames). A SUB subscribes to its key and filters
  on the first frame's prefixes exactly as a ZeroMQ SUB does.
- Requests and responses stay publications on two keys (``.../vision/request``, ``.../vision/response``) rather than
  Zenoh queries: the pairing contract (re-publication with the same id, the responder's answer cache, drop-oldest
  with an error answer, ``t_deadline``, the paper-style send()/recv()) is written once, above the transport, and
  keeps its tests on both.
- Zenoh calls back on a thread of its own. A callback only appends to a bounded deque (overflow: the oldest message is
  dropped and counted, so a stalled reader keeps the newest state) and wakes the loop with one
  ``call_soon_threadsafe``; it never blocks and never touches asyncio objects.
- One Zenoh session per process, opened on first use with :func:`configure`'s options: multicast scouting and
  gossip OFF, so nothing is discovered or announced beyond the endpoints written down (``tcp/127.0.0.1:PORT`` in
  the defaults and tests). A process either listens (``mode="router"``: it routes between the others) or connects
  to one that does (``mode="client"``).
- Presence: :func:`declare_node` declares a liveliness token ``aioadept/<cell>/<node>``;
  :class:`aioadept.bus.presence.NodeWatcher` reports each node appearing and vanishing.
"""

from __future__ import annotations

import asyncio
import collections
import json
import logging
import re
import threading
from collections.abc import AsyncIterator, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import zmq

from aioadept.errors import BusError

__all__ = [
    "DEFAULT_CELL",
    "DEFAULT_ROUTER",
    "PREFIX",
    "MODES",
    "ZenohOptions",
    "ZenohSocket",
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
_LOCATOR = re.compile(r"^tcp/(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.\-]+):(?P<port>[0-9]{1,5})$")


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
    """``tcp/HOST:PORT`` or raises :class:`BusError` (one line naming it)."""
    m = _LOCATOR.match(text.strip())
    if m is None or not 0 < int(m["port"]) <= 0xFFFF:
        raise BusError(f"Zenoh endpoint {text!r}: expected tcp/HOST:PORT with a port 1..65535, e.g. "
                       f"{DEFAULT_ROUTER!r}")
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

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise BusError(f"Zenoh mode {self.mode!r}: expected one of {', '.join(MODES)}")
        for loc in (*self.connect, *self.listen):
            check_locator(loc)
        if self.mode == "router" and not self.listen:
            raise BusError("a Zenoh router needs a listen endpoint (tcp/127.0.0.1:PORT)")
        if self.mode == "client" and not self.connect:
            raise BusError("a Zenoh client needs a router to connect to (tcp/127.0.0.1:PORT)")

    @classmethod
    def router(cls, listen: str = DEFAULT_ROUTER, *, lowlatency: bool = True) -> ZenohOptions:
        return cls(mode="router", connect=(), listen=(listen,), lowlatency=lowlatency)

    @classmethod
    def client(cls, connect: str = DEFAULT_ROUTER, *, lowlatency: bool = True) -> ZenohOptions:
        return cls(mode="client", connect=(connect,), listen=(), lowlatency=lowlatency)

    def config(self) -> Any:
        """The ``zenoh.Config``: these endpoints, no multicast scouting, no gossip."""
        zenoh = _zenoh()
        cfg = zenoh.Config()
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
            zenoh.init_log_from_env_or("error")
            try:
                _session = zenoh.open(_options.config())
            except Exception as exc:  # zenoh.ZError: e.g. a router that does not answer, a port in use
                raise BusError(f"cannot open the Zenoh session ({_options.mode}, connect "
                               f"{list(_options.connect)}, listen {list(_options.listen)}): {exc}") from exc
        return _session


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


# ------------------------------------------------------------------------------------------------- sockets


class ZenohSocket:
    """The part of a ZeroMQ PUB or SUB socket the bus uses, over one Zenoh key.

    ``flavour`` as in :mod:`aioadept.bus.sockets`: ``plain`` (read with ``recv_multipart(zmq.NOBLOCK)`` after the
    wake-up callback set by :meth:`set_reader`), ``asyncio`` (``await recv_multipart()``) or ``thread``
    (``poll``/blocking ``recv_multipart``). A SUB keeps at most ``hwm`` messages; beyond that the oldest is
    dropped (``dropped`` counts them). ``max_bytes`` (ZeroMQ's MAXMSGSIZE) drops bigger messages.
    """

    def __init__(self, kind: int, key: str, *, flavour: str = "plain", hwm: int = 1000,
                 topics: Iterable[bytes] = (), max_bytes: int | None = None) -> None:
        if kind not in (zmq.PUB, zmq.SUB):
            raise BusError(f"the Zenoh transport has PUB and SUB sockets only, not {kind}")
        self.kind = kind
        self.key = check_key(key, wildcards=kind == zmq.SUB)
        self.flavour = flavour
        self.closed = False
        self.dropped = 0
        self._topics: list[bytes] = list(topics)
        self._max_bytes = max_bytes
        self._queue: collections.deque[list[bytes]] = collections.deque(maxlen=max(1, hwm))
        self._cond = threading.Condition()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._on_ready: Any = None
        self._scheduled = False
        self._waiter: asyncio.Future | None = None
        self._entity: Any = None

    @property
    def endpoint(self) -> str:
        return PREFIX + self.key

    def declare(self) -> str:
        """Declare the Zenoh publisher or subscriber; returns the endpoint in use."""
        zenoh = _zenoh()
        s = session()
        try:
            if self.kind == zmq.PUB:
                self._entity = s.declare_publisher(self.key, express=True)
            else:
                # indirect (Zenoh's default): the callback runs on a Python thread of its own, not on Zenoh's
                # network thread; taking the GIL on the network thread stalled Zenoh's own I/O behind our event loop
                # (request/response p50 about 1.4x slower in benchmarks/bench_bus.py).
                self._entity = s.declare_subscriber(self.key, zenoh.handlers.Callback(self._on_sample,
                                                                                      indirect=True))
        except Exception as exc:
            self.closed = True
            raise BusError(f"cannot declare a Zenoh {'publisher' if self.kind == zmq.PUB else 'subscriber'} on "
                           f"{self.key!r}: {exc}") from exc
        return self.endpoint

    # -- options (the ZeroMQ ones the bus sets) ------------------------------------------------------------

    def setsockopt(self, option: int, value: Any) -> None:
        if option == zmq.SUBSCRIBE:
            self._topics.append(bytes(value))
        elif option == zmq.UNSUBSCRIBE:
            self._topics.remove(bytes(value))
        elif option == zmq.MAXMSGSIZE:
            self._max_bytes = None if value < 0 else int(value)
        elif option in (zmq.RCVHWM, zmq.SNDHWM):
            self._queue = collections.deque(self._queue, maxlen=max(1, int(value)))
        # LINGER and the rest mean nothing here.

    # -- sending -------------------------------------------------------------------------------------------

    def send(self, payload: bytes, flags: int = 0) -> None:
        self._put(payload, None)

    def send_multipart(self, frames: Any, flags: int = 0) -> None:
        frames = list(frames)
        if len(frames) == 1:
            self._put(frames[0], None)
        elif len(frames) == 2:
            self._put(frames[1], frames[0])
        else:
            raise BusError(f"the Zenoh transport carries 1 or 2 frames, not {len(frames)}")

    def _put(self, payload: bytes, topic: bytes | None) -> None:
        if self.closed:
            raise zmq.ZMQError(zmq.ENOTSOCK, "Zenoh socket closed")
        if self.kind != zmq.PUB:
            raise zmq.ZMQError(zmq.ENOTSUP, "send on a SUB socket")
        try:
            if topic is None:
                self._entity.put(bytes(payload))
            else:
                self._entity.put(bytes(payload), attachment=bytes(topic))
        except Exception as exc:
            raise zmq.ZMQError(zmq.EFAULT, f"Zenoh put on {self.key!r} failed: {exc}") from exc

    # -- receiving -----------------------------------------------------------------------------------------

    def _accepts(self, frames: list[bytes]) -> bool:
        if self._max_bytes is not None and sum(map(len, frames)) > self._max_bytes:
            return False
        first = frames[0]
        return any(first.startswith(t) for t in self._topics)

    def _on_sample(self, sample: Any) -> None:
        # On a Zenoh thread: append and wake, nothing else (never block, never touch asyncio objects).
        try:
            payload = sample.payload.to_bytes()
            att = sample.attachment
            frames = [payload] if att is None else [att.to_bytes(), payload]
        except Exception as exc:  # pragma: no cover - a malformed sample from Zenoh itself
            log.debug("Zenoh sample on %s unreadable: %r", self.key, exc)
            return
        if self.closed or not self._accepts(frames):
            return
        queue = self._queue
        if len(queue) == queue.maxlen:
            self.dropped += 1
        queue.append(frames)  # one atomic step under the GIL: no lock on the hot path
        if self.flavour == "thread":
            with self._cond:
                self._cond.notify()
            return
        loop = self._loop
        if loop is not None and not self._scheduled:
            # At most one wake-up queued: _wake clears the flag before it drains, so a message appended after the
            # drain started schedules a new one (a rare double wake-up is harmless).
            self._scheduled = True
            try:
                loop.call_soon_threadsafe(self._wake)
            except RuntimeError:  # the loop is closed: nobody reads any more
                pass

    def _wake(self) -> None:
        # On the loop's thread.
        self._scheduled = False
        waiter, self._waiter = self._waiter, None
        if waiter is not None and not waiter.done():
            waiter.set_result(None)
        if self._on_ready is not None and not self.closed:
            self._on_ready()

    def set_reader(self, loop: asyncio.AbstractEventLoop, on_ready: Any) -> None:
        """Call ``on_ready()`` on ``loop`` whenever messages have arrived (None: stop)."""
        with self._cond:
            self._loop = loop if on_ready is not None else self._loop
            self._on_ready = on_ready
            pending = bool(self._queue)
        if pending and on_ready is not None:
            loop.call_soon(self._wake)

    def _pop(self) -> list[bytes] | None:
        try:
            return self._queue.popleft()
        except IndexError:
            return None

    def recv_multipart(self, flags: int = 0) -> Any:
        if self.flavour == "asyncio":
            return self._recv_async()
        return self._recv_sync(block=not flags & zmq.NOBLOCK)

    def _recv_sync(self, *, block: bool, timeout_s: float | None = None) -> list[bytes]:
        if not block:
            try:
                return self._queue.popleft()
            except IndexError:
                if self.closed:
                    raise zmq.ZMQError(zmq.ENOTSOCK, "Zenoh socket closed") from None
                raise zmq.Again() from None
        with self._cond:
            while not self._queue:
                if self.closed:
                    raise zmq.ZMQError(zmq.ENOTSOCK, "Zenoh socket closed")
                if not block:
                    raise zmq.Again()
                if not self._cond.wait(timeout_s):
                    raise zmq.Again()
            return self._queue.popleft()

    async def _recv_async(self) -> list[bytes]:
        loop = asyncio.get_running_loop()
        with self._cond:
            self._loop = loop
        while True:
            frames = self._pop()
            if frames is not None:
                return frames
            if self.closed:
                raise zmq.ZMQError(zmq.ENOTSOCK, "Zenoh socket closed")
            self._waiter = loop.create_future()
            if self._queue:  # arrived between the pop and the waiter
                continue
            try:
                await self._waiter
            finally:
                self._waiter = None

    def poll(self, timeout_ms: int = -1, flags: int = zmq.POLLIN) -> int:
        with self._cond:
            if not self._queue and not self.closed:
                self._cond.wait(None if timeout_ms < 0 else timeout_ms / 1000)
            return zmq.POLLIN if self._queue else 0

    def close(self, linger: int | None = None) -> None:
        if self.closed:
            return
        self.closed = True
        entity, self._entity = self._entity, None
        if entity is not None:
            try:
                entity.undeclare()
            except Exception as exc:
                log.debug("Zenoh undeclare %s: %r", self.key, exc)
        with self._cond:
            self._cond.notify_all()
        waiter, self._waiter = self._waiter, None
        if waiter is not None and not waiter.done():
            waiter.cancel()

    def __repr__(self) -> str:
        return f"<ZenohSocket {'PUB' if self.kind == zmq.PUB else 'SUB'} {self.key}{' closed' if self.closed else ''}>"


def make_zenoh_socket(kind: int, endpoint: str, *, flavour: str = "plain", hwm: int = 1000,
                      topics: Iterable[bytes] = (), options: Mapping[int, int] = {}) -> ZenohSocket:
    """A :class:`ZenohSocket` for ``endpoint`` (not declared yet: :meth:`ZenohSocket.declare`)."""
    max_bytes = options.get(zmq.MAXMSGSIZE)
    unknown = set(options) - {zmq.MAXMSGSIZE}
    if unknown:
        raise BusError(f"socket options {sorted(unknown)} have no meaning on the Zenoh transport")
    return ZenohSocket(kind, key_of(endpoint), flavour=flavour, hwm=hwm, topics=topics,
                       max_bytes=None if max_bytes is None or max_bytes < 0 else max_bytes)
