"""The responder side of request/response pairing: a node answers request events (the EPypes node's role).

Data path (docs/bus.md)::

    requester PUB --request_endpoint--> SUB  SocketReader -> triage (cache, deadline, queue bound)
                                              -> handler(type, id, attributes)  (inline, worker task or thread)
    requester SUB <--response_endpoint-- PUB <- answer (LRU cache of answers by (type, id))

On Zenoh a request may also come as a query on the request key, and its answer is then the reply to that query
(not published); the triage, the cache and the queue are the same (docs/bus.md, "Requests: publications or Zenoh
queries").

The sockets come from the one socket layer (:mod:`aioadept.bus.sockets`), the queued-or-in-process requests live
in a :class:`~aioadept.bus.pairing.PendingRegistry`, and Protobuf stays in :mod:`aioadept.bus.messages`.
"""

from __future__ import annotations

import asyncio
import collections
import inspect
import logging
import math
import time
from collections.abc import Awaitable, Callable, Iterable, Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import zmq

from aioadept.bus.endpoints import peer_actual
from aioadept.bus.messages import AttributeValue, decode_event, encode_event
from aioadept.bus.pairing import PendingRegistry, response_type_for
from aioadept.bus.security import Curve
from aioadept.bus.sockets import SocketReader, as_topic, close_socket, open_socket
from aioadept.errors import BusEncodeError, BusError, ClientStateError

__all__ = ["DEFAULT_MAX_QUEUE", "DEFAULT_MAX_REQUEST_BYTES", "Handler", "Responder"]

log = logging.getLogger(__name__)

DEFAULT_MAX_QUEUE = 32
"""Requests a :class:`Responder` keeps waiting; beyond that the oldest waiting one is dropped (with an error)."""
DEFAULT_MAX_REQUEST_BYTES = 1 << 20
"""Largest request frame a :class:`Responder` reads (``ZMQ_MAXMSGSIZE``); a larger one is never parsed."""

Handler = Callable[[str, "str | None", dict], "Mapping[str, Any] | None | Awaitable[Mapping[str, Any] | None]"]

Asker = Any
"""Who gets a request's answer: None (published on the response endpoint) or a Zenoh query
(:class:`aioadept.bus.zenohsocket.QueryFrames`: ``reply(payload, topic)``, ``drop()``)."""


RESPONSE_HWM = 10_000
"""ZeroMQ's send high-water mark of the response PUB. Every request is answered once, a dropped one with an error;
under a flood those answers are published as fast as requests are read, and with ZeroMQ's default of 1000 the PUB
dropped answers silently whenever the requester's reading lagged: the likely cause of 500 consecutive of 5000
unanswered in one full-suite run on a loaded machine (tests/integration/test_vision_limits.py; not reproduced in
isolation). 10 000 answers of a few hundred bytes are a few MB at most."""


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
      outlive the cached answer under load and be processed again.) On Zenoh, where a request is a query, the
      answer goes to the newest copy's query; the older copies are let go unanswered.
    - ``request_types`` restricts which event types are answered; None answers all. Any other event (a
      ``Shutdown``, a ``VisionResponse`` echoed back, a typo) is ignored: never handled, never queued, never
      answered; ``ignored`` counts them and each is logged at debug level.
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
        is_async = inspect.iscoroutinefunction(handler) or (callable(handler)
                                                            and inspect.iscoroutinefunction(handler.__call__))
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
            context=context, topics=topics, curve=curve, queries=True,
            options={} if max_request_bytes is None else {zmq.MAXMSGSIZE: max_request_bytes})
        try:
            self._pub, self._actual_resp = open_socket(zmq.PUB, response_endpoint, bind=bind is not False,
                                                       context=context, curve=curve,  # None: publishers bind
                                                       hwm=RESPONSE_HWM)
        except BaseException:
            close_socket(self._sub)
            raise
        self._peer_req = peer_actual(request_endpoint, bool(bind), self._actual_req)
        self._peer_resp = peer_actual(response_endpoint, bind is not False, self._actual_resp)
        self._loop: asyncio.AbstractEventLoop | None = None
        # Read what is there first (up to READ_BATCH), then dispatch: under a flood the requests are triaged by the
        # queue bound instead of being processed one by one as ZeroMQ hands them over (which left the newest request
        # behind everything ZeroMQ had buffered). A lone request still goes straight to an inline handler.
        self._reader = SocketReader(self._sub, self._on_batch, name=f"Responder reader {self._actual_req}")
        # (type, id, attributes, awaitable the handler already returned or None: call the handler in turn,
        #  [asker]: who gets the answer, replaced by a repeat's)
        self._queue: collections.deque[tuple[str, str | None, dict, Any, list[Asker]]] = collections.deque()
        self._busy = False  # the worker is processing a request (keeps arrival order for the at-once path)
        # (type, id) queued or being processed -> its [asker]: a repeat of one of them is not queued again.
        self._pending: PendingRegistry[tuple[str, str], list[Asker]] = PendingRegistry("request")
        self._wakeup: asyncio.Event | None = None
        self._tasks: list[asyncio.Task] = []  # the worker, owned and cancelled by aclose()
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
        self.ignored = 0
        """Events not of a ``request_types`` type: dropped unanswered, before anything else looks at them."""

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
        self._loop = asyncio.get_running_loop()
        self._closed_event = asyncio.Event()
        self._wakeup = asyncio.Event()
        # Even an inline handler may hand back an awaitable, so the worker always exists (idle, it costs nothing).
        self._tasks.append(asyncio.create_task(self._work(), name=f"Responder worker {self._actual_req}"))
        self._reader.start()

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
        await self._reader.stop()
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            try:
                await task
            except asyncio.CancelledError:
                pass
            except Exception:
                log.exception("Responder task ended with an error")
        # Queries never answered: their askers learn it now. (The one in process, if any, went with the worker:
        # its last reference is gone, which finalizes it.)
        while self._queue:
            _let_go(self._queue.popleft()[4][0])
        close_socket(self._sub)
        close_socket(self._pub)
        if self._executor is not None:
            self._executor.shutdown(wait=False, cancel_futures=True)
        if self._closed_event is not None:
            self._closed_event.set()

    # -------------------------------------------------------------------------------------------- reading

    def _on_batch(self, batch: list[list[bytes]]) -> None:
        alone = len(batch) == 1
        for frames in batch:
            # A Zenoh query (QueryFrames) is answered by replying to it; anything else was published.
            self._dispatch(frames[-1], alone, frames if hasattr(frames, "reply") else None)

    def _dispatch(self, payload: bytes, alone: bool = True, asker: Asker = None) -> None:
        # Every path answers the asker, hands it on (queue, pending repeat) or lets it go (_let_go).
        try:
            event_type, rid, attrs = decode_event(payload)
        except BusError as exc:
            log.warning("Responder: ignoring undecodable request on %s: %s", self._actual_req, exc)
            _let_go(asker)
            return
        if self._request_types is not None and event_type not in self._request_types:
            self.ignored += 1
            log.debug("Responder on %s: ignoring a %r event (id %s): not a request type it serves; %d ignored",
                      self._actual_req, event_type, rid, self.ignored)
            _let_go(asker)
            return
        bad = self._bad_deadline(attrs)
        if bad is not None:
            self.rejected += 1
            self._send(encode_event(self._response_type or response_type_for(event_type), rid, {"error": bad}),
                       asker)
            return
        if self._answer_from_cache(event_type, rid, asker):
            return
        if self._expired(attrs):
            _let_go(asker)
            return
        if rid is not None:
            holder = self._pending.get((event_type, rid))
            if holder is not None:
                # A repeat of a request still queued or in process: its answer will serve it, sent to the newest
                # copy (a query's asker may have given up on an older one).
                _let_go(holder[0])
                holder[0] = asker
                return
        later = None
        if alone and self._inline and not self._queue and not self._busy:
            try:
                result = self._handler(event_type, rid, attrs)
            except Exception as exc:
                self._answer(event_type, rid, self._error_response(event_type, rid, exc), asker)
                return
            if not inspect.isawaitable(result):
                self._answer(event_type, rid, self._encode_result(event_type, rid, result), asker)
                return
            later = result
        if len(self._queue) >= self.max_queue:
            self._drop(self._queue.popleft())
        holder = [asker]
        if rid is not None:
            self._pending.add((event_type, rid), holder)
        self._queue.append((event_type, rid, attrs, later, holder))
        assert self._wakeup is not None
        self._wakeup.set()

    def _drop(self, item: tuple[str, str | None, dict, Any, list[Asker]]) -> None:
        """Answer a request taken off the full queue with a ``dropped:`` error, unprocessed (not cached: a re-send
        of the same id is a new request and is served if there is room then)."""
        event_type, rid, _attrs, later, holder = item
        if later is not None and hasattr(later, "close"):
            later.close()  # an un-awaited coroutine from the handler: never run, no "never awaited" warning
        if rid is not None:
            self._pending.pop((event_type, rid))
        self.dropped += 1
        if self._loop is not None and self._loop.time() >= self._next_drop_log:
            # At most one line a second: a flood must not turn into a flood of log lines.
            self._next_drop_log = self._loop.time() + 1.0
            log.warning("Responder on %s: request queue full (%d waiting), dropping the oldest; %d dropped so far",
                        self._actual_req, self.max_queue, self.dropped)
        text = (f"dropped: request queue full ({self.max_queue} waiting); the node serves the newest requests "
                f"first")
        self._send(encode_event(self._response_type or response_type_for(event_type), rid, {"error": text}),
                   holder[0])

    async def _work(self) -> None:
        queue, wakeup = self._queue, self._wakeup
        assert wakeup is not None
        while True:
            while not queue:
                wakeup.clear()
                await wakeup.wait()
            event_type, rid, attrs, later, holder = queue.popleft()
            self._busy = True
            try:
                if later is None and self._answer_from_cache(event_type, rid, holder[0]):
                    continue
                if later is None and self._expired(attrs):
                    _let_go(holder[0])
                    continue
                response = await self._process_async(event_type, rid, attrs, later)
                self._answer(event_type, rid, response, holder[0])  # the newest copy's asker (a repeat's)
            finally:
                self._busy = False
                if rid is not None:
                    self._pending.pop((event_type, rid))
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

    def _answer_from_cache(self, event_type: str, rid: str | None, asker: Asker) -> bool:
        if rid is None:
            return False
        key = (event_type, rid)
        cached = self._cache.get(key)
        if cached is None:
            return False
        self._cache.move_to_end(key)
        self.cache_hits += 1
        self._send(cached, asker)
        return True

    def _answer(self, event_type: str, rid: str | None, response: bytes, asker: Asker) -> None:
        if rid is not None:
            self._cache[(event_type, rid)] = response
            if len(self._cache) > self._cache_size:
                self._cache.popitem(last=False)
        self._send(response, asker)

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

    def _send(self, payload: bytes, asker: Asker = None) -> None:
        if asker is not None:
            try:
                asker.reply(payload, self._response_topic)
            except Exception as exc:  # the asker's session is gone, or the query already timed out
                log.debug("Responder on %s: reply to a query failed: %r", self._actual_req, exc)
            return
        try:
            if self._response_topic is None:
                self._pub.send(payload, zmq.NOBLOCK)
            else:
                self._pub.send_multipart((self._response_topic, payload), zmq.NOBLOCK)
        except zmq.Again:
            log.debug("Responder: response dropped at the high-water mark")
        except zmq.ZMQError as exc:
            log.error("Responder on %s: publish failed: %r", self._actual_resp, exc)


def _let_go(asker: Asker) -> None:
    """A request that gets no answer: a query is finalized now, so its asker learns that no reply follows."""
    if asker is not None:
        asker.drop()
