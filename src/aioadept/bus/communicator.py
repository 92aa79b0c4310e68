"""Request -> matching response over publish/subscribe: the paper's ProtobufCommunicator, and the node side.

Data path (docs/bus.md)::

    MasterControlNode                                         vision node
    Communicator.request()  --PUB connect--> request_endpoint  --SUB bind-->  Responder -> handler(type, id, attrs)
    reader task (one)      <--SUB connect-- response_endpoint <--PUB bind--   (LRU cache of answers by id)

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
import time
import uuid
from collections.abc import Awaitable, Callable, Iterable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Protocol

import zmq

from aioadept.bus import epypes_pb2
from aioadept.bus.messages import (
    AttributeValue,
    EventMessage,
    decode_event,
    encode_event,
    event_from_pb,
    event_to_pb,
)
from aioadept.bus.pubsub import DEFAULT_REQUEST_ENDPOINT, DEFAULT_RESPONSE_ENDPOINT, Publisher, Subscriber
from aioadept.errors import BusEncodeError, BusError, ClientStateError, RequestTimeout, VisionError

__all__ = [
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


def new_request_id() -> str:
    """A fresh request id: the first 8 hex characters of ``uuid4()``, as the robot protocol's message IDs."""
    return uuid.uuid4().hex[:ID_LENGTH]


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
    """Timing hooks (e.g. aioadept.capture). Both methods are optional; they must not block."""

    def on_request(self, request: Request) -> None: ...

    def on_response(self, response: Response) -> None: ...


class _Pending:
    """One outstanding request: its future, its exact bytes (re-published unchanged) and its backoff timer."""

    __slots__ = ("future", "payload", "event_type", "t_send_s", "interval_s", "handle", "publishes")

    def __init__(self, future: asyncio.Future, payload: bytes, event_type: str, t_send_s: float,
                 interval_s: float) -> None:
        self.future = future
        self.payload = payload
        self.event_type = event_type
        self.t_send_s = t_send_s
        self.interval_s = interval_s
        self.handle: asyncio.TimerHandle | None = None
        self.publishes = 1


class Communicator:
    """Publish request events and await the matching responses (the MasterControlNode side).

    ``async with Communicator(request_endpoint, response_endpoint) as comm:`` connects a PUB to the node's request
    endpoint and a SUB to its response endpoint (``bind=True`` binds both instead) and starts the one reader task;
    leaving the block cancels it, fails outstanding requests with :class:`BusError` and closes the sockets.

    ``timeout_s`` is the default per-request timeout. Until answered, a request is re-published with the same id
    after ``republish_interval_s``, then at intervals growing by ``republish_backoff`` up to
    ``republish_max_interval_s``. ``request_topic``/``response_topic`` None means single-frame messages, as EPypes
    sends and expects; give topics to share endpoints between services.
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
        bind: bool = False,
        context: zmq.Context | None = None,
    ) -> None:
        if timeout_s <= 0 or republish_interval_s <= 0 or republish_backoff < 1 or republish_max_interval_s <= 0:
            raise ValueError("timeouts and intervals must be > 0 and backoff >= 1")
        self.request_endpoint = request_endpoint
        self.response_endpoint = response_endpoint
        self.timeout_s = timeout_s
        self.republish_interval_s = republish_interval_s
        self.republish_backoff = republish_backoff
        self.republish_max_interval_s = republish_max_interval_s
        self._request_topic = request_topic
        self._response_topic = response_topic
        self._bind = bind
        self._context = context
        self._observers: list[Any] = list(observers)
        self._pending: dict[str, _Pending] = {}
        self._sent_order: collections.deque[str] = collections.deque()  # for the paper-style send()/recv()
        self._pub: Publisher | None = None
        self._sub: Subscriber | None = None
        self._reader: asyncio.Task | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._state = "new"  # new -> open -> closed; not reentrant, not reopenable
        self._reader_error: BaseException | None = None
        self.ignored_responses = 0
        """Responses that matched no outstanding request (foreign ids, duplicates, answers after a timeout)."""
        self.republished = 0
        """Re-publications done for the slow joiner / lost messages, over the communicator's life."""

    # -------------------------------------------------------------------------------------------- lifecycle

    @property
    def actual_request_endpoint(self) -> str:
        self._require_open()
        assert self._pub is not None
        return self._pub.actual_endpoint

    @property
    def actual_response_endpoint(self) -> str:
        self._require_open()
        assert self._sub is not None
        return self._sub.actual_endpoint

    async def __aenter__(self) -> Communicator:
        await self.open()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def open(self) -> None:
        """Create the sockets and start the reader task. Raises ClientStateError if already opened."""
        if self._state != "new":
            raise ClientStateError(f"Communicator is {self._state}; create a new one")
        self._loop = asyncio.get_running_loop()
        sub_topics = (b"",) if self._response_topic is None else (self._response_topic,)
        self._sub = Subscriber(self.response_endpoint, topics=sub_topics, bind=self._bind, context=self._context)
        try:
            self._pub = Publisher(self.request_endpoint, bind=self._bind, context=self._context)
        except BaseException:
            self._sub.close()
            raise
        self._state = "open"
        self._reader = asyncio.create_task(self._read_loop(), name=f"Communicator reader {self.response_endpoint}")

    async def aclose(self) -> None:
        """Stop the reader, fail outstanding requests with BusError, close the sockets. Idempotent."""
        if self._state == "closed":
            return
        self._state = "closed"
        if self._reader is not None:
            self._reader.cancel()
            try:
                await self._reader
            except asyncio.CancelledError:
                pass
            except Exception:  # already recorded by the reader itself
                pass
        self._fail_all(BusError("communicator closed"))
        for s in (self._pub, self._sub):
            if s is not None:
                s.close()

    def add_observer(self, observer: Any) -> None:
        self._observers.append(observer)

    def remove_observer(self, observer: Any) -> None:
        self._observers.remove(observer)

    # -------------------------------------------------------------------------------------------- requests

    async def request(self, event_type: str = "VisionRequest", attributes: Mapping[str, Any] | None = None, *,
                      timeout_s: float | None = None, id: str | None = None) -> Response:
        """Publish a request event and return the matching :class:`Response`.

        ``attributes`` get ``t_request`` (``time.time()``, epoch s) unless they carry one. ``timeout_s=None`` means
        the communicator's default. Raises :class:`RequestTimeout` (with ``request_id``) when nothing matching
        arrives in time, :class:`BusEncodeError` for attributes the schema cannot carry, :class:`BusError` if the
        communicator closes meanwhile. A node's ``error`` attribute is returned, not raised: see
        :meth:`Response.raise_for_error`.
        """
        rid = self._start(event_type, id, attributes)
        return await self._finish(rid, timeout_s)

    def _start(self, event_type: str, rid: str | None, attributes: Mapping[str, Any] | None) -> str:
        self._require_open()
        if self._reader_error is not None:
            raise BusError(f"communicator reader failed: {self._reader_error!r}") from self._reader_error
        if rid is None:
            rid = new_request_id()
            while rid in self._pending:  # 32 bits: collisions are rare but cheap to rule out
                rid = new_request_id()
        elif rid in self._pending:
            raise ClientStateError(f"request id {rid!r} is already outstanding")
        attrs = dict(attributes) if attributes else {}
        attrs.setdefault("t_request", time.time())
        payload = encode_event(event_type, rid, attrs)  # BusEncodeError before anything is registered
        loop = self._loop
        assert loop is not None and self._pub is not None
        pend = _Pending(loop.create_future(), payload, event_type, 0.0, self.republish_interval_s)
        # Registered before the bytes leave, so even an instant answer finds its future.
        self._pending[rid] = pend
        try:
            self._send(payload)
        except BaseException:
            del self._pending[rid]
            raise
        pend.t_send_s = loop.time()
        pend.handle = loop.call_later(pend.interval_s, self._republish, rid)
        if self._observers:
            self._notify("on_request", Request(rid, event_type, attrs, pend.t_send_s))
        return rid

    async def _finish(self, rid: str, timeout_s: float | None) -> Response:
        pend = self._pending[rid]
        timeout = self.timeout_s if timeout_s is None else timeout_s
        try:
            async with asyncio.timeout(timeout):
                response_type, attrs, t_recv_s = await pend.future
        except TimeoutError:
            if pend.future.done() and not pend.future.cancelled() and pend.future.exception() is None:
                response_type, attrs, t_recv_s = pend.future.result()  # answered as the timer fired: take it
            else:
                raise RequestTimeout(
                    f"no response to {pend.event_type} {rid} within {timeout:g} s "
                    f"(published {pend.publishes} times)", request_id=rid, publishes=pend.publishes) from None
        finally:
            if pend.handle is not None:
                pend.handle.cancel()
            self._pending.pop(rid, None)
        response = Response(rid, response_type, attrs, pend.t_send_s, t_recv_s)
        if self._observers:
            self._notify("on_response", response)
        return response

    def _send(self, payload: bytes) -> None:
        assert self._pub is not None
        if self._request_topic is None:
            self._pub.send_nowait(payload)
        else:
            self._pub.publish_nowait(self._request_topic, payload)

    def _republish(self, rid: str) -> None:
        pend = self._pending.get(rid)
        if pend is None or pend.future.done() or self._state != "open":
            return
        try:
            self._send(pend.payload)
        except BusError as exc:
            if not pend.future.done():
                pend.future.set_exception(exc)
            return
        pend.publishes += 1
        self.republished += 1
        pend.interval_s = min(pend.interval_s * self.republish_backoff, self.republish_max_interval_s)
        assert self._loop is not None
        pend.handle = self._loop.call_later(pend.interval_s, self._republish, rid)

    # -------------------------------------------------------------------------------------------- reader

    async def _read_loop(self) -> None:
        assert self._sub is not None and self._loop is not None
        sub, loop, pending = self._sub, self._loop, self._pending
        try:
            while True:
                _topic, payload = await sub.recv()
                t_recv_s = loop.time()
                try:
                    event_type, rid, attrs = decode_event(payload)
                except BusError as exc:
                    # Garbage on a shared endpoint must not kill the reader of everybody's requests.
                    log.warning("Communicator: ignoring undecodable message on %s: %s", sub.actual_endpoint, exc)
                    self.ignored_responses += 1
                    continue
                pend = pending.get(rid) if rid is not None else None
                if pend is None or pend.future.done():
                    self.ignored_responses += 1
                    continue
                pend.future.set_result((event_type, attrs, t_recv_s))
        except asyncio.CancelledError:
            raise
        except BaseException as exc:
            self._reader_error = exc
            log.error("Communicator reader on %s failed: %r", self.response_endpoint, exc)
            self._fail_all(BusError(f"communicator reader failed: {exc!r}"))
            raise

    def _fail_all(self, exc: BusError) -> None:
        for pend in self._pending.values():
            if pend.handle is not None:
                pend.handle.cancel()
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
        re-published until answered, like :meth:`request`. Pair each ``send`` with one :meth:`recv`.
        """
        if isinstance(event, EventMessage):
            event_type, rid, attrs = event.event_type, event.id, event.attributes
        elif isinstance(event, epypes_pb2.Event):
            event_type, rid, attrs = event_from_pb(event)
        else:
            raise BusEncodeError(f"send() takes an epypes Event or EventMessage, got {type(event).__name__}")
        rid = self._start(event_type, rid, attrs)
        self._sent_order.append(rid)
        return rid

    async def recv(self, *, timeout_s: float | None = None) -> epypes_pb2.Event:
        """The response to the oldest request sent with :meth:`send` and not yet received, as a Protobuf ``Event``
        (``pb_resp.attributes.entries`` as in the paper). Raises RequestTimeout / ClientStateError."""
        while self._sent_order:
            rid = self._sent_order.popleft()
            if rid in self._pending:
                response = await self._finish(rid, timeout_s)
                return event_to_pb(response.event_type, response.id, response.attributes)
        raise ClientStateError("recv() without an outstanding send()")


# ================================================================================================ node side

Handler = Callable[[str, "str | None", dict], "Mapping[str, Any] | None | Awaitable[Mapping[str, Any] | None]"]


class Responder:
    """The node side: receive request events, call ``handler(type, id, attributes)``, publish the answer.

    It binds a SUB on ``request_endpoint`` and a PUB on ``response_endpoint`` (``bind=False`` connects both). The
    handler returns the response attributes (a mapping, or None for none); it may be a coroutine function, or a
    plain function, which with ``in_thread=True`` runs in a worker thread owned by the responder so that a slow
    image graph does not stall the loop (e.g. an acquisition task in the same process).

    - The response has the request's id and type ``response_type`` (default: ``VisionRequest`` ->
      ``VisionResponse``, see :func:`response_type_for`).
    - A handler exception, or attributes the schema cannot carry, become an ``error`` attribute (STRING); the
      responder keeps serving.
    - The last ``cache_size`` answers are kept by (type, id): a repeated request (the requester re-publishing
      against the slow joiner) is answered from the cache, never processed twice.
    - Requests are handled one at a time, in arrival order; repeats that arrive meanwhile wait in ZeroMQ's queue
      and are then answered from the cache.
    - ``request_types`` restricts which event types are answered (others are ignored); None answers all.
    """

    def __init__(
        self,
        request_endpoint: str,
        response_endpoint: str,
        handler: Handler,
        *,
        bind: bool = True,
        response_type: str | None = None,
        request_types: Iterable[str] | None = None,
        cache_size: int = 64,
        in_thread: bool = False,
        request_topic: bytes | str | None = None,
        response_topic: bytes | str | None = None,
        context: zmq.Context | None = None,
    ) -> None:
        if cache_size < 1:
            raise ValueError("cache_size must be >= 1")
        self._handler = handler
        self._is_async = inspect.iscoroutinefunction(handler) or inspect.iscoroutinefunction(
            getattr(handler, "__call__", None))
        self._in_thread = in_thread and not self._is_async
        self._response_type = response_type
        self._request_types = frozenset(request_types) if request_types is not None else None
        self._cache: collections.OrderedDict[tuple[str, str], bytes] = collections.OrderedDict()
        self._cache_size = cache_size
        self._request_topic = request_topic
        self._response_topic = response_topic
        sub_topics = (b"",) if request_topic is None else (request_topic,)
        self._sub = Subscriber(request_endpoint, topics=sub_topics, bind=bind, context=context)
        try:
            self._pub = Publisher(response_endpoint, bind=bind, context=context)
        except BaseException:
            self._sub.close()
            raise
        self._executor: ThreadPoolExecutor | None = None
        self._task: asyncio.Task | None = None
        self._closed = False
        self.handled = 0
        """Requests processed by the handler."""
        self.cache_hits = 0
        """Repeated requests answered from the cache."""
        self.errors = 0
        """Requests answered with an ``error`` attribute."""

    @property
    def actual_request_endpoint(self) -> str:
        """Where requesters publish (the real port after binding to 0)."""
        return self._sub.actual_endpoint

    @property
    def actual_response_endpoint(self) -> str:
        """Where requesters subscribe (the real port after binding to 0)."""
        return self._pub.actual_endpoint

    async def __aenter__(self) -> Responder:
        self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    def start(self) -> None:
        """Start serving in a task owned by this responder (stopped by :meth:`aclose`)."""
        if self._closed:
            raise ClientStateError("Responder is closed")
        if self._task is not None:
            raise ClientStateError("Responder already started")
        self._task = asyncio.create_task(self.serve(), name=f"Responder {self.actual_request_endpoint}")

    async def wait_closed(self) -> None:
        """Wait until serving ends (after aclose(), or if it failed: then the error is raised here)."""
        if self._task is not None:
            await asyncio.shield(self._task)

    async def aclose(self) -> None:
        """Stop serving, close the sockets, shut the worker thread down (not waiting for a running handler)."""
        if self._closed:
            return
        self._closed = True
        if self._task is not None:
            self._task.cancel()
            try:
                await self._task
            except asyncio.CancelledError:
                pass
            except Exception:
                log.exception("Responder task ended with an error")
        self._sub.close()
        self._pub.close()
        if self._executor is not None:
            self._executor.shutdown(wait=False, cancel_futures=True)

    async def serve(self) -> None:
        """Serve until cancelled. Use either this or ``start()``/``async with``."""
        sub = self._sub
        while True:
            _topic, payload = await sub.recv()
            try:
                event_type, rid, attrs = decode_event(payload)
            except BusError as exc:
                log.warning("Responder: ignoring undecodable request on %s: %s", sub.actual_endpoint, exc)
                continue
            if self._request_types is not None and event_type not in self._request_types:
                continue
            key = (event_type, rid) if rid is not None else None
            if key is not None:
                cached = self._cache.get(key)
                if cached is not None:
                    self._cache.move_to_end(key)
                    self.cache_hits += 1
                    self._send(cached)
                    continue
            response = await self._process(event_type, rid, attrs)
            if key is not None:
                self._cache[key] = response
                if len(self._cache) > self._cache_size:
                    self._cache.popitem(last=False)
            self._send(response)

    async def _process(self, event_type: str, rid: str | None, attrs: dict[str, AttributeValue]) -> bytes:
        rtype = self._response_type or response_type_for(event_type)
        try:
            if self._in_thread:
                if self._executor is None:
                    self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="aioadept-responder")
                loop = asyncio.get_running_loop()
                result = await loop.run_in_executor(self._executor, self._handler, event_type, rid, attrs)
            else:
                result = self._handler(event_type, rid, attrs)
            if inspect.isawaitable(result):
                result = await result
            self.handled += 1
            return encode_event(rtype, rid, result)
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            self.errors += 1
            text = str(exc) or type(exc).__name__
            if isinstance(exc, BusEncodeError):
                text = f"response not encodable: {text}"
            else:
                log.warning("Responder handler failed on %s %s: %r", event_type, rid, exc, exc_info=exc)
            return encode_event(rtype, rid, {"error": text})

    def _send(self, payload: bytes) -> None:
        if self._response_topic is None:
            self._pub.send_nowait(payload)
        else:
            self._pub.publish_nowait(self._response_topic, payload)
