"""The one socket layer of the bus: open (options, CURVE, bind or connect), read from the event loop, close.

Every role of the bus opens its ZeroMQ sockets here: the publishers and subscribers of :mod:`aioadept.bus.pubsub`,
both sides of request/response pairing (:class:`~aioadept.bus.communicator.Communicator`,
:class:`~aioadept.bus.responder.Responder`) and the virtual camera's robot-state reader (a
:class:`~aioadept.bus.pubsub.SyncSubscriber`). What each socket gets, in this order:

1. ``LINGER 0`` (closing never waits for unsent messages) and the high-water mark of its direction;
2. further integer options (e.g. ``{zmq.MAXMSGSIZE: n}``), then SUB prefixes;
3. CURVE if ``curve`` is given (:mod:`aioadept.bus.security`);
4. bind or connect as the CZMQ endpoint says (``@`` binds, ``>`` connects, bare: the role's default;
   :mod:`aioadept.bus.endpoints`), returning the endpoint in use (the real port after binding to 0 or ``*``).

Every failure closes the socket again and becomes :class:`~aioadept.errors.BusError`. :func:`close_socket` is the
one way out (it also releases a CURVE server's share of the authenticator).

:class:`SocketReader` drives a plain socket from the loop's reader callbacks: ZeroMQ's FD wakes the loop and the
reader hands every queued message straight to its owner, without a task switch or a future per message (most of
our overhead over a raw ping-pong, benchmarks/bench_bus.py). Without ``loop.add_reader`` (e.g. the Windows
proactor loop) it falls back to a task awaiting zmq.asyncio.

An endpoint written ``zenoh:KEY`` gets a :class:`~aioadept.bus.zenohsocket.ZenohSocket` instead (the same calls, over
Eclipse Zenoh): :func:`make_socket` creates it, :func:`attach` declares it, :class:`SocketReader` is woken by its
callback instead of a file descriptor, :func:`close_socket` undeclares it.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Iterable, Mapping
from typing import Literal

import zmq
import zmq.asyncio

from aioadept.bus import security
from aioadept.bus.endpoints import resolve
from aioadept.bus.zenoh import is_zenoh
from aioadept.bus.security import Curve
from aioadept.errors import BusError

__all__ = ["SocketReader", "as_topic", "attach", "close_socket", "make_socket", "open_socket"]

log = logging.getLogger(__name__)

Flavour = Literal["plain", "asyncio", "thread"]
"""``plain``: a synchronous socket on the asyncio context (sends never wait; read through :class:`SocketReader`);
``asyncio``: a zmq.asyncio socket (awaitable receives); ``thread``: a synchronous socket on the plain process-wide
context, for one plain thread."""

READ_BATCH = 256
"""Messages a :class:`SocketReader` reads in one go before it lets the loop run (and calls itself again)."""


def as_topic(topic: bytes | str) -> bytes:
    """A topic as the bytes of its first frame (str is UTF-8 encoded)."""
    if isinstance(topic, bytes):
        return topic
    if isinstance(topic, str):
        return topic.encode()
    raise BusError(f"topic must be bytes or str, got {type(topic).__name__}")


def _context(context: zmq.Context | None, flavour: Flavour) -> zmq.Context:
    if flavour == "thread":
        return context if context is not None else zmq.Context.instance()
    if context is None:
        # Process-wide and never terminated by us: terminating a shared context would break every other socket.
        return zmq.asyncio.Context.instance()
    if isinstance(context, zmq.asyncio.Context):
        return context
    # A plain context given by the caller: shadow it (no ownership, the caller terminates it).
    return zmq.asyncio.Context.shadow(context.underlying)


def make_socket(kind: int, *, context: zmq.Context | None = None, flavour: Flavour = "plain", hwm: int = 1000,
                topics: Iterable[bytes | str] = (), options: Mapping[int, int] = {},
                endpoint: str | None = None, replies_into: zmq.Socket | None = None,
                queries: bool = False) -> zmq.Socket:
    """A new socket, not yet bound or connected: ``LINGER 0``, ``hwm`` for its direction (RCVHWM for a SUB,
    SNDHWM otherwise), ``options``, and for a SUB the ``topics`` prefixes. Raises :class:`BusError`.

    An ``endpoint`` given here that is ``zenoh:KEY`` makes a Zenoh socket (:mod:`aioadept.bus.zenoh`) instead.
    Requests may be Zenoh queries there: ``replies_into`` (a PUB's) is the SUB that receives the replies to the
    queries it sends (a ZeroMQ SUB there: publications), ``queries`` (a SUB's) receives queries too. ZeroMQ has no
    queries: both mean nothing to it (its requests and answers are publications)."""
    if endpoint is not None and is_zenoh(endpoint):
        from aioadept.bus.zenohsocket import make_zenoh_socket

        subs = [as_topic(t) for t in topics] if kind == zmq.SUB else []
        if replies_into is not None and not is_zenoh_socket(replies_into):
            replies_into = None  # answers come back on ZeroMQ: the requests are publications, as there
        return make_zenoh_socket(kind, endpoint, flavour=flavour, hwm=hwm, topics=subs,  # type: ignore[return-value]
                                 options=options, replies_into=replies_into,  # type: ignore[arg-type]
                                 queries=queries)
    ctx = _context(context, flavour)
    sock = ctx.socket(kind) if flavour == "asyncio" else zmq.Socket(ctx, kind)
    opt: int = zmq.LINGER
    value: object = 0
    try:
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.RCVHWM if kind == zmq.SUB else zmq.SNDHWM, hwm)
        for opt, value in options.items():
            sock.setsockopt(opt, value)
        if kind == zmq.SUB:
            for t in topics:
                sock.setsockopt(zmq.SUBSCRIBE, as_topic(t))
    except zmq.ZMQError as exc:
        sock.close(linger=0)
        raise BusError(f"socket option {opt} = {value!r}: {exc}") from exc
    except BaseException:
        sock.close(linger=0)
        raise
    return sock


def attach(sock: zmq.Socket, endpoint: str, bind: bool, curve: Curve | None = None) -> tuple[str, bool]:
    """Set up CURVE if asked, then bind or connect ``sock`` as ``endpoint`` says (``bind``: the role's default for a
    bare address); return ``(endpoint in use, bound)``. On failure the socket is closed and :class:`BusError`
    raised. A Zenoh socket is declared on its key instead (never "bound")."""
    if is_zenoh_socket(sock):
        if curve is not None:
            close_socket(sock)
            raise BusError(f"endpoint {endpoint!r}: CURVE is ZeroMQ's; the Zenoh transport has no CURVE "
                           "(docs/bus.md, Zenoh)")
        try:
            return sock.declare(), False  # type: ignore[attr-defined]
        except BaseException:
            close_socket(sock)
            raise
    try:
        address, bind = resolve(endpoint, bind)
    except BusError:
        sock.close(linger=0)
        raise
    try:
        security.apply_curve(sock, curve)
        if bind:
            sock.bind(address)
            return sock.getsockopt_string(zmq.LAST_ENDPOINT), True
        sock.connect(address)
        return address, False
    except BaseException as exc:
        close_socket(sock)
        if not isinstance(exc, zmq.ZMQError):
            raise
        verb = "bind" if bind else "connect"
        raise BusError(f"cannot {verb} {address!r}: {exc}") from exc


def open_socket(kind: int, endpoint: str, *, bind: bool, context: zmq.Context | None = None,
                topics: Iterable[bytes | str] = (), hwm: int = 1000,
                curve: Curve | None = None, options: Mapping[int, int] = {},
                replies_into: zmq.Socket | None = None, queries: bool = False) -> tuple[zmq.Socket, str]:
    """A plain (synchronous) socket on the asyncio context, set up by :func:`make_socket` and :func:`attach`;
    returns ``(socket, actual_endpoint)``. The caller owns it and closes it with :func:`close_socket`.
    Raises :class:`BusError`."""
    sock = make_socket(kind, context=context, hwm=hwm, topics=topics, options=options, endpoint=endpoint,
                       replies_into=replies_into, queries=queries)
    return sock, attach(sock, endpoint, bind, curve)[0]


def is_zenoh_socket(sock: object) -> bool:
    """Whether ``sock`` is a :class:`~aioadept.bus.zenohsocket.ZenohSocket` (checked without importing Zenoh)."""
    return hasattr(sock, "set_reader")


def nobody_takes(sock: zmq.Socket) -> bool:
    """True when the transport knows that nothing takes what ``sock`` sends: a Zenoh PUB with no matching
    subscriber (or queryable, sending queries). ZeroMQ cannot tell: False."""
    return is_zenoh_socket(sock) and sock.matched() is False  # type: ignore[attr-defined]


def close_socket(sock: zmq.Socket) -> None:
    """Close a socket at once (linger 0), releasing its CURVE authenticator share if any. Idempotent."""
    if is_zenoh_socket(sock):
        sock.close()
        return
    security.release(sock)
    if not sock.closed:
        sock.close(linger=0)


class SocketReader:
    """Hands every message arriving on ``sock`` to ``on_batch(list of frame lists)``, from the loop's thread.

    Up to :data:`READ_BATCH` messages are read before ``on_batch`` is called (so its owner can triage a flood) and
    the loop runs other callbacks before the next batch. A ZeroMQ error while reading goes to ``on_error`` (default:
    logged); the owner decides whether to :meth:`stop`. ``on_batch`` must not raise.
    """

    def __init__(self, sock: zmq.Socket, on_batch: Callable[[list[list[bytes]]], None], *, name: str,
                 on_error: Callable[[BaseException], None] | None = None) -> None:
        self._sock = sock
        self._on_batch = on_batch
        self._on_error = on_error
        self.name = name
        self._loop: asyncio.AbstractEventLoop | None = None
        self._fd: int | None = None
        self._task: asyncio.Task | None = None

    @property
    def reading(self) -> bool:
        return self._fd is not None or (self._task is not None and not self._task.done())

    def start(self) -> None:
        """Start reading on the running loop."""
        loop = self._loop = asyncio.get_running_loop()
        if is_zenoh_socket(self._sock):
            # Woken by the Zenoh callback (through the socket's own eventfd) instead of a ZeroMQ FD; -1: "reading".
            self._fd = -1
            self._sock.set_reader(loop, self._on_readable)  # type: ignore[attr-defined]
            return
        fd = self._sock.getsockopt(zmq.FD)
        try:
            loop.add_reader(fd, self._on_readable)
        except NotImplementedError:  # e.g. the Windows proactor loop: let zmq.asyncio do the polling
            self._task = loop.create_task(self._read_loop(), name=self.name)
        else:
            self._fd = fd
            # The FD is edge-triggered: anything queued before registration would never signal. Drain once.
            loop.call_soon(self._on_readable)

    def stop_nowait(self) -> None:
        """Stop reading at once (the fallback task, if any, is cancelled; :meth:`stop` awaits it)."""
        if self._fd == -1:
            self._sock.set_reader(self._loop, None)  # type: ignore[attr-defined]
        elif self._fd is not None and self._loop is not None:
            self._loop.remove_reader(self._fd)
        self._fd = None
        if self._task is not None:
            self._task.cancel()

    async def stop(self) -> None:
        """Stop reading and wait for the fallback task, if any. Idempotent."""
        self.stop_nowait()
        task, self._task = self._task, None
        if task is not None:
            try:
                await task
            except asyncio.CancelledError:
                pass
            except Exception:  # already reported through on_error
                pass

    def _failed(self, exc: BaseException) -> None:
        if self._on_error is None:
            log.error("%s: receive failed: %r", self.name, exc)
        else:
            self._on_error(exc)

    def _on_readable(self) -> None:
        sock = self._sock
        if self._fd == -1:  # a Zenoh socket: its queue is taken in one call
            if sock.closed:
                return
            batch = sock.drain(READ_BATCH)  # type: ignore[attr-defined]
            if len(batch) >= READ_BATCH:
                assert self._loop is not None
                self._loop.call_soon(self._on_readable)
            if batch:
                self._on_batch(batch)
            return
        batch = []
        while self._fd is not None and not sock.closed:
            try:
                batch.append(sock.recv_multipart(zmq.NOBLOCK))
            except zmq.Again:
                break
            except zmq.ZMQError as exc:
                if batch:
                    self._on_batch(batch)
                    batch = []
                self._failed(exc)
                break
            if len(batch) >= READ_BATCH:
                # More may be waiting, and the FD is edge-triggered (it will not signal them again): come back after
                # the loop has run other callbacks (workers, signals).
                assert self._loop is not None
                self._loop.call_soon(self._on_readable)
                break
        if batch:
            self._on_batch(batch)

    async def _read_loop(self) -> None:
        sock = zmq.asyncio.Socket.from_socket(self._sock)
        try:
            while True:
                self._on_batch([await sock.recv_multipart()])
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            self._failed(exc)
