"""The publish and subscribe roles of the bus: owned PUB/SUB sockets with topic frames (the robot state stream, the
virtual camera's state reader, tools). Sockets are opened and closed by the one socket layer,
:mod:`aioadept.bus.sockets`, which request/response pairing uses too.

Frames on the wire:

- ``publish(topic, payload)`` sends two frames ``[topic, payload]``; subscribers filter on the topic frame prefix.
- ``send(payload)`` sends one frame, as EPypes nodes do (their SUB sockets ``recv()`` single frames with prefix
  ``""``). Use it towards EPypes peers.
- ``Subscriber.recv()`` accepts both and returns ``(topic, payload)``, with ``topic == b""`` for a single frame.
- ``SyncPublisher`` / ``SyncSubscriber`` are the same roles for one plain thread.

Endpoints are CZMQ style (:mod:`aioadept.bus.endpoints`): ``@addr`` binds, ``>addr`` connects, a bare address
takes the socket's ``bind`` argument, whose default follows pyadept/EPypes: publishers bind, subscribers connect.

Every socket is created in the constructor (so a bound socket's real port is known at once through
``actual_endpoint``), has ``LINGER 0`` and is closed by ``close()`` / ``async with``. Without an explicit
``context`` the process-wide ``zmq.asyncio.Context.instance()`` is used and never terminated by us: terminating a
shared context would break every other socket in the process. ZeroMQ errors become :class:`BusError`.

Every constructor takes ``curve=`` (default None: plain TCP, as EPypes). A :class:`aioadept.bus.security.CurveServer`
or :class:`~aioadept.bus.security.CurveClient` turns on CURVE authentication and encryption (docs/security.md).
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import AsyncIterator, Iterable
from typing import Any

import zmq

from aioadept.bus.security import Curve
from aioadept.bus.sockets import as_topic, attach, close_socket, make_socket
from aioadept.errors import BusError

__all__ = [
    "DEFAULT_REQUEST_ENDPOINT", "DEFAULT_RESPONSE_ENDPOINT", "DEFAULT_STATE_ENDPOINT", "Publisher",
    "SyncPublisher", "Subscriber", "SyncSubscriber"
]

from aioadept import defaults as _defaults  # noqa: E402

log = logging.getLogger(__name__)

DEFAULT_REQUEST_ENDPOINT = _defaults.REQUEST_ENDPOINT
"""Vision requests: the MCN's PUB binds, the node's SUB connects, as in pyadept/EPypes (docs/interfaces.md)."""
DEFAULT_RESPONSE_ENDPOINT = _defaults.RESPONSE_ENDPOINT
"""Vision responses: the node's PUB binds, the MCN's SUB connects."""
DEFAULT_STATE_ENDPOINT = _defaults.STATE_ENDPOINT
"""Robot state stream (topic ``robot.state``): the sim's PUB binds."""


class _Owned:
    """Shared lifetime of one owned socket."""

    _sock: zmq.Socket
    _endpoint: str
    _actual: str
    _bind: bool

    @property
    def endpoint(self) -> str:
        """The endpoint as given."""
        return self._endpoint

    @property
    def actual_endpoint(self) -> str:
        """The endpoint in use: after binding to port 0 or ``*`` this has the real port (``LAST_ENDPOINT``)."""
        return self._actual

    @property
    def bound(self) -> bool:
        return self._bind

    @property
    def closed(self) -> bool:
        return self._sock.closed

    def close(self) -> None:
        """Close the socket at once (linger 0: unsent messages are dropped). Idempotent."""
        if not self._sock.closed:
            close_socket(self._sock)

    def __repr__(self) -> str:
        state = "closed" if self.closed else ("bound" if self._bind else "connected")
        return f"<{type(self).__name__} {state} {self._actual}>"


class _PublisherBase(_Owned):
    def _publish(self, topic: bytes | str, payload: bytes) -> None:
        try:
            self._sock.send_multipart((as_topic(topic), payload), zmq.NOBLOCK)
        except zmq.Again:
            # Only reachable if a peer's queue is full with a non-dropping option; PUB normally drops silently.
            log.debug("%r: dropped a message (high-water mark)", self)
        except zmq.ZMQError as exc:
            raise BusError(f"publish on {self._actual} failed: {exc}") from exc

    def _send(self, payload: bytes) -> None:
        try:
            self._sock.send(payload, zmq.NOBLOCK)
        except zmq.Again:
            log.debug("%r: dropped a message (high-water mark)", self)
        except zmq.ZMQError as exc:
            raise BusError(f"send on {self._actual} failed: {exc}") from exc


class Publisher(_PublisherBase):
    """An asyncio-side PUB socket.

    A bare ``endpoint`` binds (``bind=True``, the default: publishers bind, as in EPypes); ``>addr`` or
    ``bind=False`` connects.
    A PUB socket never blocks: with no subscriber, or a full queue, ZeroMQ drops the message. The ``*_nowait``
    methods are therefore the real work and may be called from callbacks on the loop's thread; the ``async``
    ones exist for symmetry with :class:`Subscriber`. For other threads use :class:`SyncPublisher`.
    """

    def __init__(self, endpoint: str, *, bind: bool = True, context: zmq.Context | None = None,
                 sndhwm: int = 1000, curve: Curve | None = None) -> None:
        # A plain (synchronous) socket on the asyncio context: sends never wait, so the asyncio machinery of
        # zmq.asyncio (a future per send) would be pure overhead on the hot path.
        self._sock = make_socket(zmq.PUB, context=context, flavour="plain", hwm=sndhwm,
                                 endpoint=endpoint)
        self._endpoint = endpoint
        self._actual, self._bind = attach(self._sock, endpoint, bind, curve)

    def publish_nowait(self, topic: bytes | str, payload: bytes) -> None:
        """Send ``[topic, payload]``. Raises :class:`BusError` if the socket is closed."""
        self._publish(topic, payload)

    def send_nowait(self, payload: bytes) -> None:
        """Send the single frame ``payload`` (EPypes style)."""
        self._send(payload)

    async def publish(self, topic: bytes | str, payload: bytes) -> None:
        """Send ``[topic, payload]``."""
        self._publish(topic, payload)

    async def send(self, payload: bytes) -> None:
        """Send the single frame ``payload`` (EPypes style)."""
        self._send(payload)

    async def __aenter__(self) -> Publisher:
        return self

    async def __aexit__(self, *exc: object) -> None:
        self.close()


class SyncPublisher(_PublisherBase):
    """A PUB socket for a plain thread (a camera grab loop, a simulator thread). Use it from ONE thread only.

    Same frames as :class:`Publisher`; ``with SyncPublisher(...) as pub:`` closes it. Without ``context`` it uses the
    process-wide ``zmq.Context.instance()``.
    """

    def __init__(self, endpoint: str, *, bind: bool = True, context: zmq.Context | None = None,
                 sndhwm: int = 1000, curve: Curve | None = None) -> None:
        self._sock = make_socket(zmq.PUB, context=context, flavour="thread", hwm=sndhwm, endpoint=endpoint)
        self._endpoint = endpoint
        self._actual, self._bind = attach(self._sock, endpoint, bind, curve)

    def publish(self, topic: bytes | str, payload: bytes) -> None:
        """Send ``[topic, payload]``; never blocks."""
        self._publish(topic, payload)

    def send(self, payload: bytes) -> None:
        """Send the single frame ``payload`` (EPypes style); never blocks."""
        self._send(payload)

    def __enter__(self) -> SyncPublisher:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Subscriber(_Owned):
    """An asyncio SUB socket. ``topics`` are subscription prefixes of the first frame (``b""``: everything).

    ``Subscriber(endpoint)`` connects (subscribers connect, as in EPypes); ``@addr`` or ``bind=True`` binds.
    ``await sub.recv()`` returns ``(topic, payload)``; ``async for topic, payload in sub`` loops until closed.

    ``queries=True`` (a node written by hand, reading a :class:`~aioadept.bus.Communicator`'s requests): on Zenoh,
    where requests are queries, receive those too, as messages. Each is let go unanswered once read, so answer by
    publishing on the response endpoint, as on ZeroMQ, where it means nothing.
    """

    def __init__(self, endpoint: str, *, topics: Iterable[bytes | str] = (b"",), bind: bool = False,
                 context: zmq.Context | None = None, rcvhwm: int = 1000, curve: Curve | None = None,
                 queries: bool = False) -> None:
        self._sock = make_socket(zmq.SUB, context=context, flavour="asyncio", hwm=rcvhwm, endpoint=endpoint,
                                 queries=queries)
        self._topics: list[bytes] = []
        try:
            for t in topics:
                self.subscribe(t)
        except BaseException:
            close_socket(self._sock)
            raise
        self._endpoint = endpoint
        self._actual, self._bind = attach(self._sock, endpoint, bind, curve)

    @property
    def topics(self) -> tuple[bytes, ...]:
        return tuple(self._topics)

    def subscribe(self, topic: bytes | str) -> None:
        t = as_topic(topic)
        self._sock.setsockopt(zmq.SUBSCRIBE, t)
        self._topics.append(t)

    def unsubscribe(self, topic: bytes | str) -> None:
        t = as_topic(topic)
        self._sock.setsockopt(zmq.UNSUBSCRIBE, t)
        self._topics.remove(t)

    async def recv(self) -> tuple[bytes, bytes]:
        """The next message as ``(topic, payload)``; a single-frame message has topic ``b""``.

        Raises :class:`BusError` if the socket is closed or a message has more than two frames.
        """
        try:
            frames: list[Any] = await self._sock.recv_multipart()
        except zmq.ZMQError as exc:
            raise BusError(f"receive on {self._actual} failed: {exc}") from exc
        except asyncio.CancelledError:
            # pyzmq cancels pending receives when the socket is closed under them; that is not a cancellation of
            # our task, so report it as the closed socket it is.
            task = asyncio.current_task()
            if self._sock.closed and task is not None and not task.cancelling():
                raise BusError(f"{self._actual}: socket closed while receiving") from None
            raise
        if len(frames) == 2:
            return frames[0], frames[1]
        if len(frames) == 1:
            return b"", frames[0]
        raise BusError(f"expected 1 or 2 frames on {self._actual}, got {len(frames)}")

    def __aiter__(self) -> AsyncIterator[tuple[bytes, bytes]]:
        return self._iterate()

    async def _iterate(self) -> AsyncIterator[tuple[bytes, bytes]]:
        while not self.closed:
            try:
                yield await self.recv()
            except BusError:
                if self.closed:
                    return
                raise

    async def __aenter__(self) -> Subscriber:
        return self

    async def __aexit__(self, *exc: object) -> None:
        self.close()


class SyncSubscriber(_Owned):
    """A SUB socket for a plain thread (e.g. the virtual camera's robot-state reader). Use it from ONE thread only.

    Same frames and defaults as :class:`Subscriber` (connects unless ``@addr`` or ``bind=True``); without
    ``context`` it uses the process-wide ``zmq.Context.instance()``. ``recv(timeout_s)`` returns ``(topic,
    payload)`` or None when nothing came in time, so a reader thread can look at its stop flag regularly;
    ``with SyncSubscriber(...) as sub:`` closes it.
    """

    def __init__(self, endpoint: str, *, topics: Iterable[bytes | str] = (b"",), bind: bool = False,
                 context: zmq.Context | None = None, rcvhwm: int = 1000, curve: Curve | None = None) -> None:
        self._topics = tuple(as_topic(t) for t in topics)
        self._sock = make_socket(zmq.SUB, context=context, flavour="thread", hwm=rcvhwm, topics=self._topics,
                                 endpoint=endpoint)
        self._endpoint = endpoint
        self._actual, self._bind = attach(self._sock, endpoint, bind, curve)

    @property
    def topics(self) -> tuple[bytes, ...]:
        return self._topics

    def recv(self, timeout_s: float | None = None) -> tuple[bytes, bytes] | None:
        """The next message as ``(topic, payload)`` (topic ``b""`` for a single frame), or None if none arrived
        within ``timeout_s`` (None: wait for ever). Raises :class:`BusError` if the socket is closed or a message
        has more than two frames."""
        if timeout_s is not None and not (0 <= timeout_s < math.inf):
            raise ValueError(f"timeout_s must be a finite number >= 0 or None, got {timeout_s!r}")
        try:
            if timeout_s is not None and not self._sock.poll(round(timeout_s * 1000), zmq.POLLIN):
                return None
            frames: list[Any] = self._sock.recv_multipart()
        except zmq.ZMQError as exc:
            raise BusError(f"receive on {self._actual} failed: {exc}") from exc
        if len(frames) == 2:
            return frames[0], frames[1]
        if len(frames) == 1:
            return b"", frames[0]
        raise BusError(f"expected 1 or 2 frames on {self._actual}, got {len(frames)}")

    def __enter__(self) -> SyncSubscriber:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
