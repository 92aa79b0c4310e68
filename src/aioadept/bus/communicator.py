"""The requester side of request/response pairing: the paper's ProtobufCommunicator (the MasterControlNode's role).

Data path (docs/bus.md)::

    MasterControlNode                                         vision node
    Communicator.request()  --PUB bind----> request_endpoint  --SUB connect-->  Responder -> handler(type, id, attrs)
    SocketReader (one)     <--SUB connect-- response_endpoint <--PUB bind--     (LRU cache of answers by id)

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
- One reader (:class:`~aioadept.bus.sockets.SocketReader`) routes responses to a future per id, so concurrent
  requests are fine. Outstanding requests live in a :class:`~aioadept.bus.pairing.PendingRegistry`: registered
  before the bytes leave, removed the moment they settle (answered, timed out, failed, cancelled, closed), whether
  or not anybody awaits them yet (the paper-style ``send()`` without ``recv()``).

Observers get :class:`Request` (on the first publish) and :class:`Response`; their ``t_*_s`` are ``loop.time()``.
The node side, :class:`~aioadept.bus.responder.Responder`, lives in :mod:`aioadept.bus.responder`; the names both
sides share in :mod:`aioadept.bus.pairing`.
"""

from __future__ import annotations

import asyncio
import collections
import logging
import math
import time
from collections.abc import Iterable, Mapping
from typing import Any

import zmq

from aioadept.bus import epypes_pb2
from aioadept.bus.endpoints import parse_endpoint, peer_actual
from aioadept.bus.messages import EventMessage, decode_event, encode_event, event_from_pb, event_to_pb
from aioadept.bus.pairing import (
    PendingRegistry,
    Request,
    Response,
    new_request_id,
)
from aioadept.bus.pubsub import DEFAULT_REQUEST_ENDPOINT, DEFAULT_RESPONSE_ENDPOINT
from aioadept.bus.security import Curve
from aioadept.bus.sockets import SocketReader, as_topic, close_socket, nobody_takes, open_socket
from aioadept.errors import BusEncodeError, BusError, ClientStateError, RequestTimeout

__all__ = ["MAX_UNRECEIVED", "Communicator"]

log = logging.getLogger(__name__)

MAX_UNRECEIVED = 1024
"""Requests made with :meth:`Communicator.send` and not yet taken by :meth:`Communicator.recv` that are kept (with
their outcome); beyond that the oldest is forgotten, with a warning: a caller that never calls recv() must not grow
memory without bound."""


class _Pending:
    """One outstanding request: its future, its exact bytes (re-published unchanged) and its backoff timer."""

    __slots__ = ("id", "future", "payload", "event_type", "attributes", "t_send_s", "interval_s", "handle",
                 "deadline", "publishes")

    def __init__(self, rid: str, future: asyncio.Future, payload: bytes, event_type: str, t_send_s: float,
                 interval_s: float) -> None:
        self.id = rid
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

    ``queries=True``: on Zenoh, send each request (and each re-send) as a Zenoh query on the request key, whose
    replies arrive with the published answers; the pairing is unchanged. A :class:`Responder` answers both, and so
    may any Zenoh queryable taking the Protobuf event (a service in another language). Default False: publications,
    which cost less here (docs/bus.md, "Requests: publications or Zenoh queries"). Meaningless on ZeroMQ.
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
        queries: bool = False,
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
        self.queries = queries
        self._context = context
        self._curve = curve
        self._observers: list[Any] = list(observers)
        self._pending: PendingRegistry[str, _Pending] = PendingRegistry("request")
        # The paper-style send()/recv(): requests in send order, kept (with their outcome) until recv() takes them.
        self._sent_order: collections.deque[_Pending] = collections.deque()
        self._pub: zmq.Socket | None = None
        self._sub: zmq.Socket | None = None
        self._actual_req = self._actual_resp = ""
        self._reader: SocketReader | None = None
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
        return self._pending.keys()

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
        self._loop = asyncio.get_running_loop()
        topics = (b"",) if self._response_topic is None else (self._response_topic,)
        self._sub, self._actual_resp = open_socket(zmq.SUB, self.response_endpoint,
                                                   bind=bool(self._bind),  # None: subscribers connect
                                                   context=self._context, topics=topics, curve=self._curve)
        try:
            self._pub, self._actual_req = open_socket(zmq.PUB, self.request_endpoint,
                                                      bind=self._bind is not False,  # None: publishers bind
                                                      context=self._context, curve=self._curve,
                                                      replies_into=self._sub if self.queries else None)
        except BaseException:
            close_socket(self._sub)
            raise
        self._state = "open"
        # The hot path: ZeroMQ's FD wakes the loop and the reader routes every queued response straight to its
        # future (no task switch, no future per message; benchmarks/bench_bus.py).
        self._reader = SocketReader(self._sub, self._on_batch, name=f"Communicator reader {self._actual_resp}",
                                    on_error=self._reader_failed)
        self._reader.start()

    async def aclose(self) -> None:
        """Stop reading, fail outstanding requests with BusError, close the sockets. Idempotent."""
        if self._state == "closed":
            return
        self._state = "closed"
        if self._reader is not None:
            await self._reader.stop()
        self._fail_all(BusError("communicator closed"))
        for sock in (self._pub, self._sub):
            if sock is not None:
                close_socket(sock)

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
        return await self._finish(self._start(event_type, id, attributes, timeout_s))

    def _start(self, event_type: str, rid: str | None, attributes: Mapping[str, Any] | None,
               timeout_s: float | None) -> _Pending:
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
        # Registered before the bytes leave, so even an instant answer finds its future (ClientStateError for an id
        # still outstanding).
        pend = self._pending.add(rid, _Pending(rid, loop.create_future(), payload, event_type, 0.0, first_interval))
        try:
            self._send(payload)
        except BaseException:
            self._pending.pop(rid)
            raise
        pend.t_send_s = loop.time()
        pend.attributes = attrs
        pend.handle = loop.call_at(pend.t_send_s + pend.interval_s, self._republish, rid)
        self._arm_deadline(pend, timeout_s)
        if self._observers:
            self._notify("on_request", Request(rid, event_type, attrs, pend.t_send_s))
        return pend

    def _arm_deadline(self, pend: _Pending, timeout_s: float | None) -> None:
        # A timer that fails the future, rather than an asyncio.timeout() scope around the await: one timer per
        # request either way, but no cancellation round trip through the awaiting task.
        if pend.deadline is not None:
            pend.deadline.cancel()
        timeout = self.timeout_s if timeout_s is None else timeout_s
        assert self._loop is not None
        pend.deadline = self._loop.call_later(timeout, self._expire, pend, timeout)

    def _settle(self, pend: _Pending) -> None:
        """Take a request out of the registry (idempotent): it is answered, failed, or nobody waits any more."""
        pend.cancel_timers()
        if self._pending.get(pend.id) is pend:
            self._pending.pop(pend.id)

    def _expire(self, pend: _Pending, timeout: float) -> None:
        self._settle(pend)
        if not pend.future.done():
            why = ""
            if self._pub is not None and nobody_takes(self._pub):
                # Zenoh knows it: a node that is down, or in another cell, or behind another router (the usual
                # mistake in a cell spread over machines) shows here instead of as a silent timeout.
                what = "queryable" if self.queries else "subscriber"
                why = (f"; nothing on the bus takes requests on {self._actual_req} (no Zenoh {what} matches): is "
                       f"the node running, in this cell, connected to this router?")
            pend.future.set_exception(RequestTimeout(
                f"no response to {pend.event_type} {pend.id} within {timeout:g} s (published {pend.publishes} "
                f"times){why}", request_id=pend.id, publishes=pend.publishes))

    async def _finish(self, pend: _Pending) -> Response:
        try:
            response_type, attrs, t_recv_s = await pend.future
        finally:
            self._settle(pend)  # also when the awaiting task is cancelled
        response = Response(pend.id, response_type, attrs, pend.t_send_s, t_recv_s)
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
            self._settle(pend)
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

    def _on_batch(self, batch: list[list[bytes]]) -> None:
        assert self._loop is not None
        t_recv_s = self._loop.time()
        for frames in batch:
            self._route(frames, t_recv_s)

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
        self._settle(pend)
        pend.future.set_result((event_type, attrs, t_recv_s))
        self._joined = True

    def _reader_failed(self, exc: BaseException) -> None:
        self._reader_error = exc
        log.error("Communicator reader on %s failed: %r", self._actual_resp, exc)
        if self._reader is not None:
            self._reader.stop_nowait()
        self._fail_all(BusError(f"communicator reader failed: {exc!r}"))

    def _fail_all(self, exc: BusError) -> None:
        for pend in self._pending.drain():
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
        pend = self._start(event_type, rid, attrs, None)
        # Nobody awaits the future until recv(): mark its exception retrieved, or asyncio would log "Future
        # exception was never retrieved" for a request that timed out or was closed before recv() took it.
        pend.future.add_done_callback(_retrieve)
        self._sent_order.append(pend)
        if len(self._sent_order) > MAX_UNRECEIVED:
            old = self._sent_order.popleft()
            self._settle(old)
            if not old.future.done():
                old.future.cancel()
            log.warning("Communicator: more than %d requests sent without recv(); forgot the oldest (%s)",
                        MAX_UNRECEIVED, old.id)
        return pend.id

    async def recv(self, *, timeout_s: float | None = None) -> epypes_pb2.Event:
        """The response to the oldest request sent with :meth:`send` and not yet received, as a Protobuf ``Event``
        (``pb_resp.attributes.entries`` as in the paper). Raises RequestTimeout / ClientStateError."""
        if not self._sent_order:
            raise ClientStateError("recv() without an outstanding send()")
        pend = self._sent_order.popleft()
        if timeout_s is not None and not pend.future.done():
            self._arm_deadline(pend, timeout_s)
        response = await self._finish(pend)
        return event_to_pb(response.event_type, response.id, response.attributes)


def _retrieve(future: asyncio.Future) -> None:
    if not future.cancelled():
        future.exception()
