"""Request -> matching response over publish/subscribe: the paper's ProtobufCommunicator, and the node side.

Data path (docs/bus.md)::

    MasterControlNode                                         vision node
    Communicator.request()  --PUB bind----> request_endpoint  --SUB connect-->  Responder -> handler(type, id, attrs)
    reader task (one)      <--SUB connect-- response_endpoint <--PUB bind--     (LRU cache of answers by id)

Who binds: each endpoint's CZMQ prefix (``@`` binds, ``>`` connects; :mod:`aioadept.bus.endpoints`), else the
role's default as in pyadept/EPypes: publishers bind, subscribers connect (``bind=True``/``False`` instead makes
every bare endpoint of that side bind/connect). ``peer_request_endpoint``/``peer_response_endpoint`` give the
other side's explicit endpoints.

- Each request gets a fresh 8-hex id (like the robot message IDs) and a ``t_request`` attribute (``time.time()``).
- The response is the first event carrying that id; responses with another id (another requester's, or a request
  already answered or abandoned) are ignored and counted in ``ignored_responses``.
- ZeroMQ's slow joiner (a PUB drops what it sends before the connection and subscription are up) is handled
  without sleeping: until answered, the same bytes (same id) are re-published with exponential backoff. The
  Responder answers a repeated id from its cache and never runs the handler twice for one id.
- One reader task routes responses to a future per id, so concurrent requests are fine.

Observers get :class:`Request` (on the first publish) and :class:`Response`; their ``t_*_s`` are ``loop.time()``.
"""

from __future__ import annotations

import asyncio
import collections
import inspect
import logging
import math
import os
import time
from collections.abc import Awaitable, Callable, Iterable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Protocol

import zmq
import zmq.asyncio

from aioadept.bus import epypes_pb2
from aioadept.bus.endpoints import parse_endpoint, peer_actual
from aioadept.bus.messages import (
    AttributeValue,
    EventMessage,
    decode_event,
    encode_event,
    event_from_pb,
    event_to_pb,
)
from aioadept.bus.pubsub import (
    DEFAULT_REQUEST_ENDPOINT,
    DEFAULT_RESPONSE_ENDPOINT,
    as_topic,
    close_socket,
    open_socket,
)
from aioadept.bus.security import Curve
from aioadept.errors import BusEncodeError, BusError, ClientStateError, RequestTimeout, VisionError

__all__ = [
    "DEFAULT_MAX_QUEUE",
    "DEFAULT_MAX_REQUEST_BYTES",
    "BusObserver",
    "Communicator",
    "Handler",
    "Request",
    "Responder",
    "Response",
    "new_request_id",
    "response_type_for",
]

log = logging.getLogger(__name__)

ID_LENGTH = 8

DEFAULT_MAX_QUEUE = 32
"""Requests a :class:`Responder` keeps waiting; beyond that the oldest waiting one is dropped (with an error)."""
DEFAULT_MAX_REQUEST_BYTES = 1 << 20
"""Largest request frame a :class:`Responder` reads (``ZMQ_MAXMSGSIZE``); a larger one is never parsed."""
READ_BATCH = 256
"""Requests the Responder's socket callback reads in one go before it lets the loop run (and calls itself again)."""


def new_request_id() -> str:
    """A fresh request id: 8 random lowercase hex characters, the format of the robot protocol's message IDs
    (``uuid4().hex[:8]``). Drawn from ``os.urandom`` directly: same 32 random bits, a tenth of uuid4's cost."""
    return os.urandom(ID_LENGTH // 2).hex()


def response_type_for(request_type: str) -> str:
    """``"VisionRequest"`` -> ``"VisionResponse"``; a type not ending in ``Request`` gets ``Response`` appended."""
    if request_type.endswith("Request"):
        return request_type[: -len("Request")] + "Response"
    return request_type + "Response"


@dataclass(frozen=True, slots=True)
class Request:
    """A request as published (first time); ``t_send_s`` is ``loop.time()`` at the first publish."""

    id: str
    event_type: str
    attributes: dict
    t_send_s: float


@dataclass(frozen=True, slots=True)
class Response:
    """The response matched to a request; ``t_send_s``/``t_recv_s`` are ``loop.time()`` at first publish/receipt."""

    id: str
    event_type: str
    attributes: dict
    t_send_s: float
    t_recv_s: float

    @property
    def latency_s(self) -> float:
        return self.t_recv_s - self.t_send_s

    @property
    def error(self) -> str | None:
        """The node's ``error`` attribute (docs/interfaces.md), or None."""
        err = self.attributes.get("error")
        return None if err is None else str(err)

    def raise_for_error(self) -> Response:
        """Raise :class:`VisionError` (with the attributes) if the node answered with an ``error``; else self."""
        if "error" in self.attributes:
            raise VisionError(f"{self.event_type} {self.id}: {self.attributes['error']}", attributes=self.attributes)
        return self


class BusObserver(Protocol):
    """Timing hooks (e.g. aioadept.capture). Every method is optional; none may block; exceptions are logged.

    ``on_request`` is called once per request, at its first publish; ``on_republish`` (an aioadept extension) at
    each re-publication of the same id, with that moment as ``t_send_s``; ``on_response`` when it is matched.
    """

    def on_request(self, request: Request) -> None: ...

    def on_republish(self, request: Request) -> None: ...

    def on_response(self, response: Response) -> None: ...


class _Pending:
    """One outstanding request: its future, its exact bytes (re-published unchanged) and its backoff timer."""

    __slots__ = ("future", "payload", "event_type", "attributes", "t_send_s", "interval_s", "handle", "deadline",
                 "publishes")

    def __init__(self, future: asyncio.Future, payload: bytes, event_type: str, t_send_s: float,
                 interval_s: float) -> None:
        self.future = future
        self.payload = payload
        self.event_type = event_type
        self.attributes: dict = {}
        self.t_send_s = t_send_s
        self.interval_s = interval_s
        self.handle: asyncio.TimerHandle | None = None  # next re-publication
        self.deadline: asyncio.TimerHandle | None = None  # fails the future with RequestTimeout
        self.publishes = 1

    def cancel_timers(self) -> None:
        if self.handle is not None:
            self.handle.cancel()
        if self.deadline is not None:
            self.deadline.cancel()


class Communicator:
    """Publish request events and await the matching responses (the MasterControlNode side).

    ``async with Communicator(request_endpoint, response_endpoint) as comm:`` opens a PUB on the request endpoint
    (binds unless ``>addr``) and a SUB on the response endpoint (connects unless ``@addr``; ``bind=True``/``False``
    makes both bare endpoints bind/connect) and starts reading responses;
    leaving the block stops reading, fails outstanding requests with :class:`BusError` and closes the sockets.

    ``timeout_s`` is the default per-request timeout. Until answered, a request is re-published with the same id
    after ``republish_interval_s``, then at intervals growing by ``republish_backoff`` up to
    ``republish_max_interval_s``; once any answer has arrived (the node's subscription is live), requests start at
    ``republish_max_interval_s``. ``request_topic``/``response_topic`` None means single-frame messages, as EPypes
    sends and expects; give topics to share endpoints between services. ``curve`` (default None: off) secures
    both sockets with CURVE: normally a :class:`aioadept.bus.security.CurveClient` holding the node's public key
    (docs/security.md).
    """

    def __init__(
        self,
        request_endpoint: str = DEFAULT_REQUEST_ENDPOINT,
        response_endpoint: str = DEFAULT_RESPONSE_ENDPOINT,
        *,
        timeout_s: float = 5.0,
        observers: Iterable[Any] = (),
        republish_interval_s: float = 0.02,
        republish_backoff: float = 2.0,
        republish_max_interval_s: float = 0.5,
        request_topic: bytes | str | None = None,
        response_topic: bytes | str | None = None,
        bind: bool | None = None,
        context: zmq.Context | None = None,
        curve: Curve | None = None,
    ) -> None:
        # Parsed here, so a bad endpoint fails at construction with the reason (not at open()).
        parse_endpoint(request_endpoint), parse_endpoint(response_endpoint)
        if not (0 < timeout_s < math.inf and 0 < republish_interval_s < math.inf and 1 <= republish_backoff < math.inf
                and 0 < republish_max_interval_s < math.inf):  # written so that NaN fails every test
            raise ValueError("timeouts and intervals must be finite and > 0, and backoff finite and >= 1")
        self.request_endpoint = request_endpoint
        self.response_endpoint = response_endpoint
        self.timeout_s = timeout_s
        self.republish_interval_s = republish_interval_s
        self.republish_backoff = republish_backoff
        self.republish_max_interval_s = republish_max_interval_s
        self._request_topic = None if request_topic is None else as_topic(request_topic)
        self._response_topic = None if response_topic is None else as_topic(response_topic)
        self._bind = bind
        self._context = context
        self._curve = curve
        self._observers: list[Any] = list(observers)
        self._pending: dict[str, _Pending] = {}
        self._sent_order: collections.deque[str] = collections.deque()  # for the paper-style send()/recv()
        self._pub: zmq.Socket | None = None
        self._sub: zmq.Socket | None = None
        self._actual_req = self._actual_resp = ""
        self._fd: int | None = None  # registered with loop.add_reader
        self._reader: asyncio.Task | None = None  # fallback reader where the loop has no add_reader
        self._loop: asyncio.AbstractEventLoop | None = None
        self._state = "new"  # new -> open -> closed; not reentrant, not reopenable
        self._reader_error: BaseException | None = None
        self.ignored_responses = 0
        """Responses that matched no outstanding request (foreign ids, duplicates, answers after a timeout)."""
        self.republished = 0
        # Set by the first answer: the node's subscription is known to be live, so a request no longer needs the
        # fast re-publication that covers the slow joiner (it only duplicated requests a node was still working on).
        self._joined = False
        """Re-publications done for the slow joiner / lost messages, over the communicator's life."""

    # -------------------------------------------------------------------------------------------- lifecycle

    @property
    def actual_request_endpoint(self) -> str:
        self._require_open()
        return self._actual_req

    @property
    def actual_response_endpoint(self) -> str:
        self._require_open()
        return self._actual_resp

    @property
    def peer_request_endpoint(self) -> str:
        """The explicit endpoint a node's request SUB uses to reach this PUB (``>addr`` if it bound, ``@addr`` if it
        connected), with the real port."""
        self._require_open()
        return peer_actual(self.request_endpoint, self._bind is not False, self._actual_req)

    @property
    def peer_response_endpoint(self) -> str:
        """The explicit endpoint a node's response PUB uses to reach this SUB."""
        self._require_open()
        return peer_actual(self.response_endpoint, bool(self._bind), self._actual_resp)

    @property
    def pending_ids(self) -> tuple[str, ...]:
        """Ids of the requests still waiting for a response."""
        return tuple(self._pending)

    async def __aenter__(self) -> Communicator:
        await self.open()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def open(self) -> None:
        """Create the sockets and start reading. Raises ClientStateError if already opened, BusError on bad
        endpoints."""
        if self._state != "new":
            raise ClientStateError(f"Communicator is {self._state}; create a new one")
        loop = self._loop = asyncio.get_running_loop()
        topics = (b"",) if self._response_topic is None else (self._response_topic,)
        self._sub, self._actual_resp = open_socket(zmq.SUB, self.response_endpoint,
                                                   bind=bool(self._bind),  # None: subscribers connect
                                                   context=self._context, topics=topics, curve=self._curve)
        try:
            self._pub, self._actual_req = open_socket(zmq.PUB, self.request_endpoint,
                                                      bind=self._bind is not False,  # None: publishers bind
                                                      context=self._context, curve=self._curve)
        except BaseException:
            close_socket(self._sub)
            raise
        self._state = "open"
        # The hot path: ZeroMQ's FD wakes the loop and _on_readable routes every queued response straight to its
        # future. Compared with a reader task awaiting zmq.asyncio futures this saves a task switch and a future
        # per message, which is most of our overhead over a raw ping-pong (benchmarks/bench_bus.py).
        fd = self._sub.getsockopt(zmq.FD)
        try:
            loop.add_reader(fd, self._on_readable)
        except NotImplementedError:  # e.g. the Windows proactor loop: let zmq.asyncio do the polling
            self._reader = asyncio.create_task(self._read_loop(), name=f"Communicator reader {self._actual_resp}")
        else:
            self._fd = fd
            # The FD is edge-triggered: anything queued before registration would never signal. Drain once.
            loop.call_soon(self._on_readable)

    async def aclose(self) -> None:
        """Stop reading, fail outstanding requests with BusError, close the sockets. Idempotent."""
        if self._state == "closed":
            return
        self._state = "closed"
        self._stop_reading()
        if self._reader is not None:
            self._reader.cancel()
            try:
                await self._reader
            except BaseException:  # cancelled, or a failure already recorded by the reader
                pass
        self._fail_all(BusError("communicator closed"))
        for sock in (self._pub, self._sub):
            if sock is not None:
                close_socket(sock)

    def _stop_reading(self) -> None:
        if self._fd is not None and self._loop is not None:
            self._loop.remove_reader(self._fd)
            self._fd = None

    def add_observer(self, observer: Any) -> None:
        self._observers.append(observer)

    def remove_observer(self, observer: Any) -> None:
        self._observers.remove(observer)

    # -------------------------------------------------------------------------------------------- requests

    async def request(self, event_type: str = "VisionRequest", attributes: Mapping[str, Any] | None = None, *,
                      timeout_s: float | None = None, id: str | None = None) -> Response:
        """Publish a request event and return the matching :class:`Response`.

        ``attributes`` get ``t_request`` (``time.time()``, epoch s) unless they carry one. ``timeout_s=None`` means
        the communicator's default. ``id`` reuses a given id instead of a fresh one (it must not be outstanding).
        Raises :class:`RequestTimeout` (with ``request_id``) when nothing matching arrives in time,
        :class:`BusEncodeError` for attributes the schema cannot carry, :class:`BusError` if the communicator
        closes meanwhile. A node's ``error`` attribute is returned, not raised: see :meth:`Response.raise_for_error`.
        ``ValueError`` at once, before anything is sent, for a ``timeout_s``, ``t_request`` or ``t_deadline`` that is
        not a finite number (> 0 for the timeout).
        """
        rid = self._start(event_type, id, attributes, timeout_s)
        return await self._finish(rid)

    def _start(self, event_type: str, rid: str | None, attributes: Mapping[str, Any] | None,
               timeout_s: float | None) -> str:
        self._require_open()
        if self._reader_error is not None:
            raise BusError(f"communicator reader failed: {self._reader_error!r}") from self._reader_error
        if timeout_s is not None and not (isinstance(timeout_s, (int, float)) and 0 < timeout_s < math.inf):
            raise ValueError(f"timeout_s must be a finite number > 0, got {timeout_s!r}")
        if attributes:
            for key in ("t_request", "t_deadline"):
                value = attributes.get(key)
                if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                          or not math.isfinite(value)):
                    raise ValueError(f"{key} must be a finite number (epoch s), got {value!r}")
        if rid is None:
            rid = new_request_id()
            while rid in self._pending:  # 32 bits: collisions are rare but cheap to rule out
                rid = new_request_id()
        elif rid in self._pending:
            raise ClientStateError(f"request id {rid!r} is already outstanding")
        attrs = dict(attributes) if attributes else {}
        if "t_request" not in attrs:
            attrs["t_request"] = time.time()
        if "t_deadline" not in attrs:
            # Copies published while a node was down stay queued in ZeroMQ and reach it when it comes back; the
            # deadline lets the node drop those whose requester has given up instead of processing them first.
            t_out = self.timeout_s if timeout_s is None else timeout_s
            if t_out is not None:
                attrs["t_deadline"] = attrs["t_request"] + t_out
        payload = encode_event(event_type, rid, attrs)  # BusEncodeError before anything is registered
        loop = self._loop
        assert loop is not None
        first_interval = self.republish_max_interval_s if self._joined else self.republish_interval_s
        pend = _Pending(loop.create_future(), payload, event_type, 0.0, first_interval)
        # Registered before the bytes leave, so even an instant answer finds its future.
        self._pending[rid] = pend
        try:
            self._send(payload)
        except BaseException:
            del self._pending[rid]
            raise
        pend.t_send_s = loop.time()
        pend.attributes = attrs
        pend.handle = loop.call_at(pend.t_send_s + pend.interval_s, self._republish, rid)
        self._arm_deadline(rid, pend, timeout_s)
        if self._observers:
            self._notify("on_request", Request(rid, event_type, attrs, pend.t_send_s))
        return rid

    def _arm_deadline(self, rid: str, pend: _Pending, timeout_s: float | None) -> None:
        # A timer that fails the future, rather than an asyncio.timeout() scope around the await: one timer per
        # request either way, but no cancellation round trip through the awaiting task.
        if pend.deadline is not None:
            pend.deadline.cancel()
        timeout = self.timeout_s if timeout_s is None else timeout_s
        assert self._loop is not None
        pend.deadline = self._loop.call_later(timeout, self._expire, rid, timeout)

    def _expire(self, rid: str, timeout: float) -> None:
        pend = self._pending.get(rid)
        if pend is not None and not pend.future.done():
            pend.future.set_exception(RequestTimeout(
                f"no response to {pend.event_type} {rid} within {timeout:g} s (published {pend.publishes} times)",
                request_id=rid, publishes=pend.publishes))

    async def _finish(self, rid: str) -> Response:
        pend = self._pending[rid]
        try:
            response_type, attrs, t_recv_s = await pend.future
        finally:
            pend.cancel_timers()
            self._pending.pop(rid, None)
        response = Response(rid, response_type, attrs, pend.t_send_s, t_recv_s)
        if self._observers:
            self._notify("on_response", response)
        return response

    def _send(self, payload: bytes) -> None:
        assert self._pub is not None
        try:
            if self._request_topic is None:
                self._pub.send(payload, zmq.NOBLOCK)
            else:
                self._pub.send_multipart((self._request_topic, payload), zmq.NOBLOCK)
        except zmq.Again:
            log.debug("Communicator: request dropped at the high-water mark; the re-publication will retry")
        except zmq.ZMQError as exc:
            raise BusError(f"publishing a request on {self._actual_req} failed: {exc}") from exc

    def _republish(self, rid: str) -> None:
        pend = self._pending.get(rid)
        if pend is None or pend.future.done() or self._state != "open":
            return
        try:
            self._send(pend.payload)
        except BusError as exc:
            pend.future.set_exception(exc)
            return
        pend.publishes += 1
        self.republished += 1
        if self._observers:
            assert self._loop is not None
            self._notify("on_republish", Request(rid, pend.event_type, pend.attributes, self._loop.time()))
        pend.interval_s = min(pend.interval_s * self.republish_backoff, self.republish_max_interval_s)
        assert self._loop is not None
        pend.handle = self._loop.call_later(pend.interval_s, self._republish, rid)

    # -------------------------------------------------------------------------------------------- reader

    def _on_readable(self) -> None:
        """Reader callback: drain every queued response (the FD is edge-triggered) and route it by id."""
        sub = self._sub
        if sub is None or sub.closed or self._fd is None:
            return
        loop = self._loop
        assert loop is not None
        while True:
            try:
                frames = sub.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return
            except zmq.ZMQError as exc:
                self._reader_failed(exc)
                return
            self._route(frames, loop.time())

    async def _read_loop(self) -> None:
        assert self._sub is not None and self._loop is not None
        sub = zmq.asyncio.Socket.from_socket(self._sub)
        loop = self._loop
        try:
            while True:
                frames = await sub.recv_multipart()
                self._route(frames, loop.time())
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            self._reader_failed(exc)

    def _route(self, frames: list[bytes], t_recv_s: float) -> None:
        payload = frames[-1]
        try:
            event_type, rid, attrs = decode_event(payload)
        except BusError as exc:
            # Garbage on a shared endpoint must not stop the reader of everybody's requests.
            log.warning("Communicator: ignoring undecodable message on %s: %s", self._actual_resp, exc)
            self.ignored_responses += 1
            return
        pend = self._pending.get(rid) if rid is not None else None
        if pend is None or pend.future.done():
            self.ignored_responses += 1
            return
        pend.future.set_result((event_type, attrs, t_recv_s))
        self._joined = True

    def _reader_failed(self, exc: BaseException) -> None:
        self._reader_error = exc
        log.error("Communicator reader on %s failed: %r", self._actual_resp, exc)
        self._stop_reading()
        self._fail_all(BusError(f"communicator reader failed: {exc!r}"))

    def _fail_all(self, exc: BusError) -> None:
        for pend in self._pending.values():
            pend.cancel_timers()
            if not pend.future.done():
                pend.future.set_exception(exc)

    def _notify(self, method: str, value: Any) -> None:
        for obs in self._observers:
            fn = getattr(obs, method, None)
            if fn is None:
                continue
            try:
                fn(value)
            except Exception:  # observers must never break the protocol path
                log.exception("bus observer %r.%s failed", obs, method)

    def _require_open(self) -> None:
        if self._state != "open":
            raise ClientStateError(f"Communicator is {self._state}; use 'async with Communicator(...)'")

    # -------------------------------------------------------------------------------------------- paper API

    async def send(self, event: epypes_pb2.Event | EventMessage) -> str:
        """Publish a request the way the paper's ``pbcomm.send(pb_req)`` does; returns its id.

        The event keeps its id if it has one (else gets a fresh one) and gets ``t_request`` unless present. It is
        re-published until answered, like :meth:`request`, and times out after the default ``timeout_s`` unless
        :meth:`recv` gives another timeout (counted from the recv call). Pair each ``send`` with one ``recv``.
        """
        if isinstance(event, EventMessage):
            event_type, rid, attrs = event.event_type, event.id, event.attributes
        elif isinstance(event, epypes_pb2.Event):
            event_type, rid, attrs = event_from_pb(event)
        else:
            raise BusEncodeError(f"send() takes an epypes Event or EventMessage, got {type(event).__name__}")
        rid = self._start(event_type, rid, attrs, None)
        self._sent_order.append(rid)
        return rid

    async def recv(self, *, timeout_s: float | None = None) -> epypes_pb2.Event:
        """The response to the oldest request sent with :meth:`send` and not yet received, as a Protobuf ``Event``
        (``pb_resp.attributes.entries`` as in the paper). Raises RequestTimeout / ClientStateError."""
        while self._sent_order:
            rid = self._sent_order.popleft()
            pend = self._pending.get(rid)
            if pend is not None:
                if timeout_s is not None:
                    self._arm_deadline(rid, pend, timeout_s)
                response = await self._finish(rid)
                return event_to_pb(response.event_type, response.id, response.attributes)
        raise ClientStateError("recv() without an outstanding send()")


# ================================================================================================ node side

Handler = Callable[[str, "str | None", dict], "Mapping[str, Any] | None | Awaitable[Mapping[str, Any] | None]"]


class Responder:
    """The node side: receive request events, call ``handler(type, id, attributes)``, publish the answer.

    It opens a SUB on ``request_endpoint`` (connects unless ``@addr`` or a port 0 / wildcard address, which can only
    be bound) and a PUB on ``response_endpoint`` (binds unless ``>addr``); ``bind=True``/``False`` makes every
    bare endpoint bind/connect. The
    handler returns the response attributes (a mapping, or None for none); it may be a coroutine function, or a
    plain function, which with ``in_thread=True`` runs in a worker thread owned by the responder so that a slow
    image graph does not stall the loop (e.g. an acquisition task in the same process). A plain function without
    ``in_thread`` runs right in the socket callback and may return either the attributes (answered at once: no
    task switch) or an awaitable of them (awaited by the responder's worker task, in arrival order): a node that
    can usually answer at once but sometimes has to wait for a frame needs no thread hop for the common case.

    - The response has the request's id and type ``response_type`` (default: ``VisionRequest`` ->
      ``VisionResponse``, see :func:`response_type_for`).
    - A handler exception, or attributes the schema cannot carry, become an ``error`` attribute (STRING); the
      responder keeps serving.
    - The last ``cache_size`` answers are kept by (type, id): a repeated request (the requester re-publishing
      against the slow joiner) is answered from the cache, never processed twice.
    - Requests are handled one at a time, in arrival order. A repeat that arrives while its request is still queued
      or being processed is dropped: the answer, published when it is ready, serves it. (Queued repeats could
      outlive the cached answer under load and be processed again.)
    - ``request_types`` restricts which event types are answered (others are ignored); None answers all.
    - Limits (docs/bus.md, "Limits"): at most ``max_queue`` requests wait; when one more arrives the **oldest**
      waiting request is dropped and answered at once with ``error = "dropped: ..."`` (the newest request is the
      one a waiting requester still cares about; a requester that re-sends gets the newest place). Requests are
      read out of ZeroMQ before any is processed, so a flood is triaged here, in bounded memory, instead of piling
      up in ZeroMQ's buffers ahead of the next request. A request whose ``t_deadline`` is present but not a finite
      number is answered with an ``error``. A request frame larger than ``max_request_bytes`` (None: no limit) is
      discarded by ZeroMQ before it is parsed (``ZMQ_MAXMSGSIZE``), which also disconnects the sender: it gets no
      answer, and whatever else it had in flight on that connection is lost (ZeroMQ reconnects it at once).

    ``async with Responder(...)`` (or ``start()``/``aclose()``, or ``await serve()``) runs it. ``curve`` (default
    None: off) secures both sockets with CURVE, normally a :class:`aioadept.bus.security.CurveServer` listing the
    requesters' public keys (docs/security.md).
    """

    def __init__(
        self,
        request_endpoint: str,
        response_endpoint: str,
        handler: Handler,
        *,
        bind: bool | None = None,
        response_type: str | None = None,
        request_types: Iterable[str] | None = None,
        cache_size: int = 64,
        in_thread: bool = False,
        request_topic: bytes | str | None = None,
        response_topic: bytes | str | None = None,
        context: zmq.Context | None = None,
        curve: Curve | None = None,
        max_queue: int = DEFAULT_MAX_QUEUE,
        max_request_bytes: int | None = DEFAULT_MAX_REQUEST_BYTES,
    ) -> None:
        if cache_size < 1:
            raise ValueError("cache_size must be >= 1")
        if isinstance(max_queue, bool) or not isinstance(max_queue, int) or max_queue < 1:
            raise ValueError(f"max_queue must be an int >= 1, got {max_queue!r}")
        if max_request_bytes is not None and (isinstance(max_request_bytes, bool)
                                              or not isinstance(max_request_bytes, int) or max_request_bytes < 1):
            raise ValueError(f"max_request_bytes must be an int >= 1 or None, got {max_request_bytes!r}")
        self.max_queue = max_queue
        self.max_request_bytes = max_request_bytes
        self._handler = handler
        is_async = inspect.iscoroutinefunction(handler) or inspect.iscoroutinefunction(
            getattr(handler, "__call__", None))
        self._in_thread = in_thread and not is_async
        # A plain function not sent to a thread runs right in the reader callback: no queue, no task switch.
        self._inline = not is_async and not self._in_thread
        self._response_type = response_type
        self._request_types = frozenset(request_types) if request_types is not None else None
        self._cache: collections.OrderedDict[tuple[str, str], bytes] = collections.OrderedDict()
        self._cache_size = cache_size
        self._response_topic = None if response_topic is None else as_topic(response_topic)
        topics = (b"",) if request_topic is None else (request_topic,)
        self._sub, self._actual_req = open_socket(
            zmq.SUB, request_endpoint, bind=bool(bind),  # None: subscribers connect
            context=context, topics=topics, curve=curve,
            options={} if max_request_bytes is None else {zmq.MAXMSGSIZE: max_request_bytes})
        try:
            self._pub, self._actual_resp = open_socket(zmq.PUB, response_endpoint, bind=bind is not False,
                                                       context=context, curve=curve)  # None: publishers bind
        except BaseException:
            close_socket(self._sub)
            raise
        self._peer_req = peer_actual(request_endpoint, bool(bind), self._actual_req)
        self._peer_resp = peer_actual(response_endpoint, bind is not False, self._actual_resp)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._fd: int | None = None
        # (type, id, attributes, awaitable the handler already returned or None: call the handler in turn)
        self._queue: collections.deque[tuple[str, str | None, dict, Any]] = collections.deque()
        self._busy = False  # the worker is processing a request (keeps arrival order for the at-once path)
        self._pending: set[tuple[str, str]] = set()  # (type, id) queued or being processed
        self._wakeup: asyncio.Event | None = None
        self._tasks: list[asyncio.Task] = []  # worker (and fallback reader), owned and cancelled by aclose()
        self._executor: ThreadPoolExecutor | None = None
        self._started = False
        self._closed = False
        self._closed_event: asyncio.Event | None = None
        self.handled = 0
        """Requests processed by the handler."""
        self.cache_hits = 0
        """Repeated requests answered from the cache."""
        self.expired = 0
        """Requests dropped unprocessed because their ``t_deadline`` had passed (their requester gave up)."""
        self.errors = 0
        """Requests answered with an ``error`` attribute by the handler (or an answer the schema cannot carry)."""
        self.dropped = 0
        """Requests dropped unprocessed because the queue was full, each answered with a ``dropped:`` error."""
        self._next_drop_log = 0.0
        self.rejected = 0
        """Requests answered with an error before processing: ``t_deadline`` not a finite number."""

    @property
    def actual_request_endpoint(self) -> str:
        """Where requesters publish (the real port after binding to 0)."""
        return self._actual_req

    @property
    def actual_response_endpoint(self) -> str:
        """Where requesters subscribe (the real port after binding to 0)."""
        return self._actual_resp

    @property
    def peer_request_endpoint(self) -> str:
        """The explicit endpoint a requester's PUB uses: ``>addr`` when this node bound its SUB (e.g. to port 0),
        ``@addr`` when it connected (the requester must bind there). Pass it to :class:`Communicator` as is."""
        return self._peer_req

    @property
    def peer_response_endpoint(self) -> str:
        """The explicit endpoint a requester's SUB uses (``>addr`` normally: the node's PUB binds)."""
        return self._peer_resp

    async def __aenter__(self) -> Responder:
        self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    def start(self) -> None:
        """Start serving on the running loop (stopped by :meth:`aclose`)."""
        if self._closed:
            raise ClientStateError("Responder is closed")
        if self._started:
            raise ClientStateError("Responder already started")
        self._started = True
        loop = self._loop = asyncio.get_running_loop()
        self._closed_event = asyncio.Event()
        self._wakeup = asyncio.Event()
        # Even an inline handler may hand back an awaitable, so the worker always exists (idle, it costs nothing).
        self._tasks.append(asyncio.create_task(self._work(), name=f"Responder worker {self._actual_req}"))
        fd = self._sub.getsockopt(zmq.FD)
        try:
            loop.add_reader(fd, self._on_readable)
        except NotImplementedError:  # e.g. the Windows proactor loop: let zmq.asyncio do the polling
            self._tasks.append(asyncio.create_task(self._read_loop(), name=f"Responder reader {self._actual_req}"))
        else:
            self._fd = fd
            loop.call_soon(self._on_readable)  # edge-triggered FD: drain what came before registration

    async def serve(self) -> None:
        """Start and serve until cancelled or closed; closes on the way out."""
        if not self._started:
            self.start()
        try:
            await self.wait_closed()
        finally:
            await self.aclose()

    async def wait_closed(self) -> None:
        """Wait until :meth:`aclose` has run."""
        if self._closed_event is None:
            raise ClientStateError("Responder not started")
        await self._closed_event.wait()

    async def aclose(self) -> None:
        """Stop serving, close the sockets, shut the worker thread down (not waiting for a running handler)."""
        if self._closed:
            return
        self._closed = True
        if self._fd is not None and self._loop is not None:
            self._loop.remove_reader(self._fd)
            self._fd = None
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            try:
                await task
            except asyncio.CancelledError:
                pass
            except Exception:
                log.exception("Responder task ended with an error")
        close_socket(self._sub)
        close_socket(self._pub)
        if self._executor is not None:
            self._executor.shutdown(wait=False, cancel_futures=True)
        if self._closed_event is not None:
            self._closed_event.set()

    # -------------------------------------------------------------------------------------------- reading

    def _on_readable(self) -> None:
        # Read what is there first (up to READ_BATCH), then dispatch: under a flood the requests are triaged by the
        # queue bound instead of being processed one by one as ZeroMQ hands them over (which left the newest request
        # behind everything ZeroMQ had buffered). A lone request still goes straight to an inline handler.
        sub = self._sub
        payloads: list[bytes] = []
        while self._fd is not None and not sub.closed:
            try:
                frames = sub.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                break
            except zmq.ZMQError as exc:
                log.error("Responder on %s: receive failed: %r", self._actual_req, exc)
                break
            payloads.append(frames[-1])
            if len(payloads) >= READ_BATCH:
                # More may be waiting, and the FD is edge-triggered (it will not signal them again): come back
                # after the loop has run other callbacks (the worker, signals).
                assert self._loop is not None
                self._loop.call_soon(self._on_readable)
                break
        alone = len(payloads) == 1
        for payload in payloads:
            self._dispatch(payload, alone)

    async def _read_loop(self) -> None:
        sub = zmq.asyncio.Socket.from_socket(self._sub)
        while True:
            frames = await sub.recv_multipart()
            self._dispatch(frames[-1], True)

    def _dispatch(self, payload: bytes, alone: bool = True) -> None:
        try:
            event_type, rid, attrs = decode_event(payload)
        except BusError as exc:
            log.warning("Responder: ignoring undecodable request on %s: %s", self._actual_req, exc)
            return
        if self._request_types is not None and event_type not in self._request_types:
            return
        bad = self._bad_deadline(attrs)
        if bad is not None:
            self.rejected += 1
            self._send(encode_event(self._response_type or response_type_for(event_type), rid, {"error": bad}))
            return
        if self._answer_from_cache(event_type, rid):
            return
        if self._expired(attrs):
            return
        if rid is not None and (event_type, rid) in self._pending:
            return  # a repeat of a request still queued or in process: its answer will serve it
        later = None
        if alone and self._inline and not self._queue and not self._busy:
            try:
                result = self._handler(event_type, rid, attrs)
            except Exception as exc:
                self._answer(event_type, rid, self._error_response(event_type, rid, exc))
                return
            if not inspect.isawaitable(result):
                self._answer(event_type, rid, self._encode_result(event_type, rid, result))
                return
            later = result
        if len(self._queue) >= self.max_queue:
            self._drop(self._queue.popleft())
        if rid is not None:
            self._pending.add((event_type, rid))
        self._queue.append((event_type, rid, attrs, later))
        assert self._wakeup is not None
        self._wakeup.set()

    def _drop(self, item: tuple[str, str | None, dict, Any]) -> None:
        """Answer a request taken off the full queue with a ``dropped:`` error, unprocessed (not cached: a re-send
        of the same id is a new request and is served if there is room then)."""
        event_type, rid, _attrs, later = item
        if later is not None and hasattr(later, "close"):
            later.close()  # an un-awaited coroutine from the handler: never run, no "never awaited" warning
        if rid is not None:
            self._pending.discard((event_type, rid))
        self.dropped += 1
        if self._loop is not None and self._loop.time() >= self._next_drop_log:
            # At most one line a second: a flood must not turn into a flood of log lines.
            self._next_drop_log = self._loop.time() + 1.0
            log.warning("Responder on %s: request queue full (%d waiting), dropping the oldest; %d dropped so far",
                        self._actual_req, self.max_queue, self.dropped)
        text = (f"dropped: request queue full ({self.max_queue} waiting); the node serves the newest requests "
                f"first")
        self._send(encode_event(self._response_type or response_type_for(event_type), rid, {"error": text}))

    async def _work(self) -> None:
        queue, wakeup = self._queue, self._wakeup
        assert wakeup is not None
        while True:
            while not queue:
                wakeup.clear()
                await wakeup.wait()
            event_type, rid, attrs, later = queue.popleft()
            self._busy = True
            try:
                if later is None and (self._answer_from_cache(event_type, rid) or self._expired(attrs)):
                    continue
                self._answer(event_type, rid, await self._process_async(event_type, rid, attrs, later))
            finally:
                self._busy = False
                if rid is not None:
                    self._pending.discard((event_type, rid))
            if queue:
                # Let the socket callback read (and triage) what arrived during this request before the next one:
                # a plain handler returns without awaiting anything, so without this a queue would be worked off
                # without the reader ever running.
                await asyncio.sleep(0)

    # -------------------------------------------------------------------------------------------- answering

    @staticmethod
    def _bad_deadline(attrs: Mapping[str, Any]) -> str | None:
        """The error text for a ``t_deadline`` that is present but not a finite number, else None. (NaN compares
        false with every time, so it would never expire; infinity would never expire either.)"""
        if "t_deadline" not in attrs:
            return None
        deadline = attrs["t_deadline"]
        if isinstance(deadline, (int, float)) and not isinstance(deadline, bool) and math.isfinite(deadline):
            return None
        shown = repr(deadline)
        if len(shown) > 40:
            shown = shown[:37] + "..."
        return f"bad request: t_deadline must be a finite number (epoch s), got {shown}"

    def _expired(self, attrs: Mapping[str, Any]) -> bool:
        """A request past its ``t_deadline`` (epoch s; clocks of the two hosts assumed in sync) is dropped."""
        deadline = attrs.get("t_deadline")
        if isinstance(deadline, (int, float)) and time.time() > deadline:
            self.expired += 1
            return True
        return False

    def _answer_from_cache(self, event_type: str, rid: str | None) -> bool:
        if rid is None:
            return False
        key = (event_type, rid)
        cached = self._cache.get(key)
        if cached is None:
            return False
        self._cache.move_to_end(key)
        self.cache_hits += 1
        self._send(cached)
        return True

    def _answer(self, event_type: str, rid: str | None, response: bytes) -> None:
        if rid is not None:
            self._cache[(event_type, rid)] = response
            if len(self._cache) > self._cache_size:
                self._cache.popitem(last=False)
        self._send(response)

    def _encode_result(self, event_type: str, rid: str | None, result: Any) -> bytes:
        try:
            response = encode_event(self._response_type or response_type_for(event_type), rid, result)
        except Exception as exc:
            return self._error_response(event_type, rid, exc)
        self.handled += 1
        return response

    async def _process_async(self, event_type: str, rid: str | None, attrs: dict[str, AttributeValue],
                             later: Any = None) -> bytes:
        try:
            if later is not None:
                result = later
            elif self._in_thread:
                if self._executor is None:
                    self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="aioadept-responder")
                loop = asyncio.get_running_loop()
                result = await loop.run_in_executor(self._executor, self._handler, event_type, rid, attrs)
            else:
                result = self._handler(event_type, rid, attrs)
            if inspect.isawaitable(result):
                result = await result
        except Exception as exc:
            return self._error_response(event_type, rid, exc)
        return self._encode_result(event_type, rid, result)

    def _error_response(self, event_type: str, rid: str | None, exc: Exception) -> bytes:
        self.errors += 1
        text = str(exc) or type(exc).__name__
        if isinstance(exc, BusEncodeError):
            text = f"response not encodable: {text}"
        else:
            log.warning("Responder handler failed on %s %s: %r", event_type, rid, exc, exc_info=exc)
        return encode_event(self._response_type or response_type_for(event_type), rid, {"error": text})

    def _send(self, payload: bytes) -> None:
        try:
            if self._response_topic is None:
                self._pub.send(payload, zmq.NOBLOCK)
            else:
                self._pub.send_multipart((self._response_topic, payload), zmq.NOBLOCK)
        except zmq.Again:
            log.debug("Responder: response dropped at the high-water mark")
        except zmq.ZMQError as exc:
            log.error("Responder on %s: publish failed: %r", self._actual_resp, exc)
