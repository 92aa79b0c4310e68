"""The client's transport: bytes between the socket (or a stream pair) and :class:`~aioadept.client.PendingCalls`.

Two ways in, one way through: on TCP, :class:`AckProtocol` feeds the registry from the transport's own
``data_received`` callback; with a ``connector`` that returns asyncio streams (tests, in-memory pairs),
:func:`read_loop` does, as a single reader task. Both stamp each chunk with the loop clock at the read.
"""

from __future__ import annotations

import asyncio
import functools
try:
    import fcntl
except ImportError:  # not on Windows: unsent_bytes sees the transport's buffer only
    fcntl = None  # type: ignore[assignment]
import logging
import socket
import sys
import time
from collections.abc import Callable
from typing import Any

log = logging.getLogger("aioadept.client")

READ_SIZE = 1 << 16
_BASE_TIME = asyncio.BaseEventLoop.time
_BASE_CREATE_FUTURE = asyncio.BaseEventLoop.create_future


def loop_fns(loop: asyncio.AbstractEventLoop) -> tuple[Any, Callable[[], float], Callable[[], asyncio.Future]]:
    """``(loop, clock, new_future)``: ``loop.time`` and ``loop.create_future`` without a Python frame each when
    they are asyncio's own (``time.monotonic()`` and ``Future(loop=loop)``, exactly what those do)."""
    clock = loop.time
    if getattr(clock, "__func__", None) is _BASE_TIME:
        clock = time.monotonic
    new_future: Callable[[], asyncio.Future] = loop.create_future
    if getattr(new_future, "__func__", None) is _BASE_CREATE_FUTURE:
        new_future = functools.partial(asyncio.Future, loop=loop)
    return loop, clock, new_future


_SIOCOUTQNSD = 0x894B  # Linux: bytes in the socket's send queue not yet sent (tcp(7))


def unsent_bytes(transport: asyncio.BaseTransport) -> int:
    """Bytes written to ``transport`` not yet on the wire: its own buffer plus, on Linux, the kernel's unsent
    queue (a peer whose receive window is closed). 0 where that cannot be known."""
    try:
        n = transport.get_write_buffer_size()  # type: ignore[attr-defined]
    except (AttributeError, NotImplementedError):
        n = 0
    sock = transport.get_extra_info("socket")
    if sock is not None and fcntl is not None:
        try:
            buf = bytearray(4)
            fcntl.ioctl(sock.fileno(), _SIOCOUTQNSD, buf)
            n += int.from_bytes(buf, sys.byteorder, signed=True)
        except (OSError, ValueError):
            pass
    return n


def set_nodelay(transport: asyncio.BaseTransport) -> None:
    """Small writes must leave at once (asyncio sets TCP_NODELAY too; uvloop may not)."""
    sock = transport.get_extra_info("socket")
    if sock is not None:
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except (OSError, AttributeError):
            pass


class AckProtocol(asyncio.Protocol):
    """The default TCP path: bytes go straight from the transport into ``feed(data, t_recv)``.

    Measured on a 2-core VM, a reader task between the stream and the registry costs one extra loop turn per
    round trip (~10-20 us, about 10 % of a loopback round trip); this protocol routes acks in the transport's own
    callback, as the bare ``readuntil`` client's wake-up does. ``on_lost(transport, exc)`` is called once when the
    connection ends; ``closed`` resolves then.
    """

    def __init__(self, feed: Callable[[bytes, float], None], clock: Callable[[], float],
                 on_lost: Callable[[asyncio.BaseTransport | None, BaseException | None], None],
                 loop: asyncio.AbstractEventLoop) -> None:
        self._feed = feed
        self._time = clock
        self._on_lost = on_lost
        self._transport: asyncio.BaseTransport | None = None
        self.closed: asyncio.Future[None] = loop.create_future()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self._transport = transport

    def data_received(self, data: bytes) -> None:
        try:
            self._feed(data, self._time())
        except Exception:  # a bug in routing must not kill the transport silently
            log.exception("RobotClient failed routing acks")

    def eof_received(self) -> bool:
        return False  # close our side too: the server hung up

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.closed.done():
            self.closed.set_result(None)
        self._on_lost(self._transport, exc)


async def read_loop(reader: asyncio.StreamReader, feed: Callable[[bytes, float], None],
                    clock: Callable[[], float]) -> BaseException | None:
    """The streams path: read until EOF, feeding every chunk; returns why it ended (None: EOF). A bug in
    ``feed`` ends it too (logged), so waiters never hang; CancelledError (close) propagates."""
    try:
        while True:
            data = await reader.read(READ_SIZE)
            if not data:
                return None
            feed(data, clock())
    except (OSError, ConnectionError) as exc:
        return exc
    except Exception as exc:  # a bug here must not leave waiters hanging forever
        log.exception("RobotClient reader failed")
        return exc
