"""The Zenoh transport's socket: what the bus's roles use of a ZeroMQ PUB or SUB socket, over one Zenoh key
(:class:`ZenohSocket`); :mod:`aioadept.bus.sockets` opens one for an endpoint written ``zenoh:KEY``. The session it
runs on, the keys and presence are :mod:`aioadept.bus.zenoh`'s.

Zenoh calls back on a thread of its own. A callback only appends to a bounded deque (overflow: the oldest message is
dropped and counted, so a stalled reader keeps the newest state) and wakes the loop; it never blocks and never
touches asyncio objects. The loop (a reader set with :meth:`ZenohSocket.set_reader`, or a task awaiting
``recv_multipart``) is woken through an eventfd of the socket's own, registered with the loop like a ZeroMQ socket's
file descriptor: one ``eventfd_write`` from Zenoh's thread, one readable event in the loop. ``call_soon_threadsafe``
(the fallback where there is no eventfd) goes through asyncio's self-pipe, a socket pair whose send, drain and extra
callback cost about 35 us of a request's round trip on the 2-core test machine (benchmarks/bench_bus.py; docs/bus.md,
Cost).

Requests and answers (docs/bus.md, "Requests: publications or Zenoh queries"): a PUB opened with ``replies_into=sub``
sends each message as a Zenoh query (``get`` on its key, from a declared querier) and hands every reply to ``sub`` as if
it had been published there; a SUB opened with ``queries=True`` also declares a queryable on its key, and each query
reaches its reader as a :class:`QueryFrames` (the frames, plus ``reply()`` to answer that one query and ``drop()`` to
let it go unanswered). The pairing contract (ids, re-sending, the answer cache) stays above, in the Communicator and
the Responder.
"""

from __future__ import annotations

import asyncio
import collections
import logging
import os
import threading
from collections.abc import Iterable, Mapping
from typing import Any

import zmq

from aioadept.bus.zenoh import PREFIX, _zenoh, check_key, key_of, plain, session
from aioadept.errors import BusError

__all__ = ["QUERY_TIMEOUT_S", "QueryFrames", "ZenohSocket", "make_zenoh_socket"]

log = logging.getLogger(__name__)

QUERY_TIMEOUT_S = 10.0
"""How long a query sent by a ``replies_into`` PUB waits for replies (Zenoh's default). The requester re-sends an
unanswered request with the same id long before that, and the responder answers the newest copy."""


class QueryFrames(list):
    """The frames of one Zenoh query (``[payload]`` or ``[topic, payload]``, the topic from its attachment), with
    what answering it takes. A list, so a reader that does not know about queries reads it like any message."""

    __slots__ = ("_query", "_key")

    def __init__(self, frames: list[bytes], query: Any, key: str) -> None:
        super().__init__(frames)
        self._query = query
        self._key = key

    def reply(self, payload: bytes, topic: bytes | None = None) -> None:
        """Answer this query (once: the query is finalized, so the asker knows no more replies follow)."""
        query, self._query = self._query, None
        if query is None:
            raise BusError("this query was already answered or let go")
        try:
            query.reply(self._key, payload, attachment=topic)
        finally:
            query.drop()

    def drop(self) -> None:
        """Finalize the query unanswered (idempotent). Letting go of the last reference does the same in CPython;
        this says so where it happens."""
        query, self._query = self._query, None
        if query is not None:
            query.drop()


class ZenohSocket:
    """The part of a ZeroMQ PUB or SUB socket the bus uses, over one Zenoh key.

    ``flavour`` as in :mod:`aioadept.bus.sockets`: ``plain`` (read with ``recv_multipart(zmq.NOBLOCK)`` after the
    wake-up callback set by :meth:`set_reader`), ``asyncio`` (``await recv_multipart()``) or ``thread``
    (``poll``/blocking ``recv_multipart``). A SUB keeps at most ``hwm`` messages; beyond that the oldest is
    dropped (``dropped`` counts them). ``max_bytes`` (ZeroMQ's MAXMSGSIZE) drops bigger messages.

    ``replies_into`` (a PUB): send each message as a query and hand its replies to that SUB. ``queries`` (a SUB):
    answer queries on the key too, each read as a :class:`QueryFrames`.
    """

    def __init__(self, kind: int, key: str, *, flavour: str = "plain", hwm: int = 1000,
                 topics: Iterable[bytes] = (), max_bytes: int | None = None,
                 replies_into: ZenohSocket | None = None, queries: bool = False) -> None:
        if kind not in (zmq.PUB, zmq.SUB):
            raise BusError(f"the Zenoh transport has PUB and SUB sockets only, not {kind}")
        if replies_into is not None and (kind != zmq.PUB or not isinstance(replies_into, ZenohSocket)
                                         or replies_into.kind != zmq.SUB):
            raise BusError("replies_into: a Zenoh PUB sends queries whose replies go to a Zenoh SUB")
        if queries and kind != zmq.SUB:
            raise BusError("queries: only a Zenoh SUB answers queries")
        self.kind = kind
        self._replies_into = replies_into
        self._queries = queries
        self._queryable: Any = None
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
        self._efd: int | None = None  # the loop's wake-up: an eventfd registered with self._loop
        self._efd_lock = threading.Lock()
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
            if self.kind == zmq.PUB and self._replies_into is not None:
                # ALL: every responder on the key is asked, as every subscriber gets a publication; NONE: each reply
                # is handed over as it arrives (the default consolidation may hold replies until the query ends).
                self._entity = s.declare_querier(self.key, target=zenoh.QueryTarget.ALL,
                                                 consolidation=zenoh.ConsolidationMode.NONE,
                                                 timeout=QUERY_TIMEOUT_S, express=True)
                # One handler for every get. On Zenoh's own thread (indirect=False): it only copies and wakes the
                # loop, where the default (indirect) would start a Python thread per query.
                self._reply_handler = zenoh.handlers.Callback(self._replies_into._on_reply, indirect=False)
            elif self.kind == zmq.PUB:
                self._entity = s.declare_publisher(self.key, express=True)
            else:
                # indirect (Zenoh's default): the callback runs on a Python thread of its own, not on Zenoh's
                # network thread; taking the GIL on the network thread stalled Zenoh's own I/O behind our event loop
                # (request/response p50 about 1.4x slower in benchmarks/bench_bus.py).
                self._entity = s.declare_subscriber(self.key, zenoh.handlers.Callback(self._on_sample,
                                                                                      indirect=True))
                if self._queries:
                    self._queryable = s.declare_queryable(self.key, zenoh.handlers.Callback(self._on_query,
                                                                                            indirect=True))
        except Exception as exc:
            self.close()
            what = ("querier" if self._replies_into is not None else "publisher" if self.kind == zmq.PUB
                    else "subscriber")
            raise BusError(f"cannot declare a Zenoh {what} on {self.key!r}: {plain(exc)}") from exc
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
            if self._replies_into is not None:
                self._entity.get(self._reply_handler, payload=bytes(payload),
                                 attachment=None if topic is None else bytes(topic))
            elif topic is None:
                self._entity.put(bytes(payload))
            else:
                self._entity.put(bytes(payload), attachment=bytes(topic))
        except Exception as exc:
            verb = "query" if self._replies_into is not None else "put"
            raise zmq.ZMQError(zmq.EFAULT, f"Zenoh {verb} on {self.key!r} failed: {plain(exc)}") from exc

    def matched(self) -> bool | None:
        """A PUB: whether anything on the network takes what it sends (a subscriber, or sending queries a
        queryable, whose key matches), from Zenoh's matching status; None when that is not known."""
        if self.kind != zmq.PUB or self._entity is None:
            return None
        try:
            status = self._entity.matching_status
        except Exception:  # pragma: no cover - a closed session
            return None
        return bool(getattr(status, "matching", status))  # a MatchingStatus, or a bool in older bindings

    # -- receiving -----------------------------------------------------------------------------------------

    def _accepts(self, frames: list[bytes]) -> bool:
        if self._max_bytes is None and b"" in self._topics:  # the usual case: everything (one test per sample)
            return True
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
        self._deliver(frames)

    def _on_reply(self, reply: Any) -> None:
        # On Zenoh's thread: a reply to a query sent by the PUB whose replies_into this is.
        sample = reply.ok
        if sample is None:
            log.debug("Zenoh query on %s answered with an error: %r", self.key, reply.err)
            return
        self._on_sample(sample)

    def _on_query(self, query: Any) -> None:
        # On a Zenoh thread, as _on_sample. A query that is not kept (closed, filtered, or pushed out of a full queue)
        # is finalized when its last reference goes, so its asker learns at once that no reply follows.
        try:
            payload = b"" if query.payload is None else query.payload.to_bytes()
            att = query.attachment
            key = self.key if "*" not in self.key else str(query.key_expr)  # a reply's key is concrete
            frames = QueryFrames([payload] if att is None else [att.to_bytes(), payload], query, key)
        except Exception as exc:  # pragma: no cover - a malformed query from Zenoh itself
            log.debug("Zenoh query on %s unreadable: %r", self.key, exc)
            query.drop()
            return
        self._deliver(frames)

    def _deliver(self, frames: list[bytes]) -> None:
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
                with self._efd_lock:  # so the loop cannot close the eventfd (and its number be reused) mid-write
                    efd = self._efd
                    if efd is not None:
                        os.eventfd_write(efd, 1)
                if efd is None:
                    loop.call_soon_threadsafe(self._wake)
            except (RuntimeError, OSError):  # the loop is closed: nobody reads any more
                pass

    def _on_efd(self) -> None:
        # On the loop's thread: the eventfd is readable.
        try:
            os.eventfd_read(self._efd)  # type: ignore[arg-type]
        except (BlockingIOError, TypeError):  # a double wake-up already drained it / closed meanwhile
            pass
        self._wake()

    def _wake(self) -> None:
        # On the loop's thread.
        self._scheduled = False
        waiter, self._waiter = self._waiter, None
        if waiter is not None and not waiter.done():
            waiter.set_result(None)
        if self._on_ready is not None and not self.closed:
            self._on_ready()

    def set_reader(self, loop: asyncio.AbstractEventLoop, on_ready: Any) -> None:
        """Call ``on_ready()`` on ``loop`` whenever messages have arrived (None: stop). On the loop's thread."""
        if on_ready is None:
            self._on_ready = None
            self._drop_efd()
            return
        self._watch(loop)
        self._on_ready = on_ready
        if self._queue:
            loop.call_soon(self._wake)

    def _watch(self, loop: asyncio.AbstractEventLoop) -> None:
        """Have ``loop`` woken when messages arrive: through an eventfd it watches, else call_soon_threadsafe."""
        if self._loop is not loop:
            self._drop_efd()
        with self._cond:
            self._loop = loop
        if self._efd is None and hasattr(os, "eventfd") and not self.closed:
            efd = os.eventfd(0, os.EFD_NONBLOCK | os.EFD_CLOEXEC)
            try:
                loop.add_reader(efd, self._on_efd)
            except NotImplementedError:  # a loop without add_reader (Windows' proactor): the self-pipe it is
                os.close(efd)
            else:
                self._efd = efd
        # A wake-up written to an eventfd dropped before the loop read it would leave the flag set and the loop deaf.
        self._scheduled = False

    def _drop_efd(self) -> None:
        # On the loop's thread (or after the loop is gone).
        with self._efd_lock:
            efd, self._efd = self._efd, None
        if efd is None:
            return
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.remove_reader(efd)
        os.close(efd)

    def drain(self, limit: int) -> list[list[bytes]]:
        """Take up to ``limit`` messages at once, without blocking (the loop's reader: one call per wake-up where
        ``recv_multipart(NOBLOCK)`` would cost a call and, at the end, a ``zmq.Again`` per wake-up)."""
        queue = self._queue
        # Counted first: the callback may append meanwhile (each popleft is atomic under the GIL).
        return [queue.popleft() for _ in range(min(len(queue), limit))]

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
        if self._loop is not loop:
            self._watch(loop)
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
        for entity in (self._entity, self._queryable):
            if entity is not None:
                try:
                    entity.undeclare()
                except Exception as exc:
                    log.debug("Zenoh undeclare %s: %r", self.key, exc)
        self._entity = self._queryable = None
        while self._queue:  # queries never read: finalized now, not whenever the socket is collected
            frames = self._queue.popleft()
            if isinstance(frames, QueryFrames):
                frames.drop()
        loop = self._loop
        if self._efd is not None:
            try:
                on_loop = loop is not None and asyncio.get_running_loop() is loop
            except RuntimeError:
                on_loop = False
            if on_loop or loop is None or loop.is_closed():
                self._drop_efd()
            else:  # removing a reader belongs to the loop's thread
                try:
                    loop.call_soon_threadsafe(self._drop_efd)
                except RuntimeError:
                    self._drop_efd()
        with self._cond:
            self._cond.notify_all()
        waiter, self._waiter = self._waiter, None
        if waiter is not None and not waiter.done():
            waiter.cancel()

    def __repr__(self) -> str:
        return f"<ZenohSocket {'PUB' if self.kind == zmq.PUB else 'SUB'} {self.key}{' closed' if self.closed else ''}>"


def make_zenoh_socket(kind: int, endpoint: str, *, flavour: str = "plain", hwm: int = 1000,
                      topics: Iterable[bytes] = (), options: Mapping[int, int] = {},
                      replies_into: ZenohSocket | None = None, queries: bool = False) -> ZenohSocket:
    """A :class:`ZenohSocket` for ``endpoint`` (not declared yet: :meth:`ZenohSocket.declare`)."""
    max_bytes = options.get(zmq.MAXMSGSIZE)
    unknown = set(options) - {zmq.MAXMSGSIZE}
    if unknown:
        raise BusError(f"socket options {sorted(unknown)} have no meaning on the Zenoh transport")
    return ZenohSocket(kind, key_of(endpoint), flavour=flavour, hwm=hwm, topics=topics,
                       max_bytes=None if max_bytes is None or max_bytes < 0 else max_bytes,
                       replies_into=replies_into, queries=queries)
