"""In-memory asyncio stream pairs: a connected (reader, writer) × 2 without sockets, for unit tests.

The two ends are real :class:`asyncio.StreamReader` / :class:`asyncio.StreamWriter` objects over a small in-memory
transport, so anything written for TCP streams (``RobotClient``, a server handler) runs on them unchanged::

    (c_reader, c_writer), (s_reader, s_writer) = stream_pair(chunk_size=1)   # deliver 1 byte at a time
    client = RobotClient(connector=memory_connector(handler))               # see memory_connector

Delivery is asynchronous (``loop.call_soon``) and in order, like a socket: a write returns before the peer sees the
bytes. ``chunk_size`` splits every write into pieces of that many bytes, each delivered as its own read, to test
framing against fragmentation.
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Awaitable, Callable
from typing import Any

__all__ = ["MemoryTransport", "memory_connector", "stream_pair"]

StreamEnd = tuple[asyncio.StreamReader, asyncio.StreamWriter]


class MemoryTransport(asyncio.Transport):
    """One end of an in-memory byte pipe; ``write`` delivers to the peer end's protocol on the next loop turn."""

    def __init__(self, loop: asyncio.AbstractEventLoop, protocol: asyncio.Protocol, *,
                 chunk_size: int | None = None, name: str = "memory") -> None:
        super().__init__({"peername": (name, 0), "sockname": (name, 0)})
        self._loop = loop
        self._protocol = protocol
        self._chunk_size = chunk_size
        self.peer: MemoryTransport | None = None
        self._closing = False
        self._eof_sent = False
        self._lost = False
        self.bytes_written = 0
        self._outbox: deque[tuple[str, bytes]] = deque()
        self._pumping = False

    # --- Transport API used by StreamWriter
    def write(self, data: bytes | bytearray | memoryview) -> None:
        if self._closing or self._eof_sent:
            return  # like a socket transport after close: the bytes go nowhere
        data = bytes(data)
        if not data:
            return
        self.bytes_written += len(data)
        step = self._chunk_size or len(data)
        for i in range(0, len(data), step):
            self._post("data", data[i:i + step])

    def _post(self, kind: str, data: bytes = b"") -> None:
        # Everything (data, EOF, close) goes out in order, one item per loop turn (each pump schedules the next),
        # so a reader really sees fragments one by one instead of finding them all buffered at its next wake-up.
        self._outbox.append((kind, data))
        if not self._pumping:
            self._pumping = True
            self._loop.call_soon(self._pump)

    def _pump(self) -> None:
        if not self._outbox:
            self._pumping = False
            return
        kind, data = self._outbox.popleft()
        peer = self.peer
        if kind == "data":
            if peer is not None:
                peer._deliver(data)
        elif kind == "eof":
            if peer is not None:
                peer._deliver_eof()
        elif kind == "close":
            self._connection_lost(None)
            if peer is not None:
                peer._peer_closed()
        self._loop.call_soon(self._pump)

    def writelines(self, list_of_data: Any) -> None:
        self.write(b"".join(list_of_data))

    def can_write_eof(self) -> bool:
        return True

    def write_eof(self) -> None:
        if self._eof_sent:
            return
        self._eof_sent = True
        self._post("eof")

    def is_closing(self) -> bool:
        return self._closing

    def close(self) -> None:
        """Close both directions after what was written: the peer reads EOF, then both ends see
        ``connection_lost``."""
        if self._closing:
            return
        self._closing = True
        if not self._eof_sent:
            self._eof_sent = True
            self._post("eof")
        self._post("close")

    def abort(self) -> None:
        """Like a reset: unsent bytes are dropped and the peer sees ``connection_lost(ConnectionResetError)``."""
        if self._lost:
            return
        self._closing = True
        self._eof_sent = True
        self._outbox.clear()
        self._loop.call_soon(self._connection_lost, None)
        if self.peer is not None:
            self._loop.call_soon(self.peer._connection_lost, ConnectionResetError("memory peer aborted"))

    def get_write_buffer_size(self) -> int:
        return 0

    def get_write_buffer_limits(self) -> tuple[int, int]:
        return (0, 0)

    def set_write_buffer_limits(self, high: int | None = None, low: int | None = None) -> None:
        pass

    def pause_reading(self) -> None:
        pass  # memory delivery is already bounded by the test

    def resume_reading(self) -> None:
        pass

    def is_reading(self) -> bool:
        return not self._lost

    def get_protocol(self) -> asyncio.BaseProtocol:
        return self._protocol

    def set_protocol(self, protocol: asyncio.BaseProtocol) -> None:
        self._protocol = protocol  # type: ignore[assignment]

    # --- delivery from the peer
    def _deliver(self, data: bytes) -> None:
        if not self._lost:
            self._protocol.data_received(data)

    def _deliver_eof(self) -> None:
        if not self._lost:
            self._protocol.eof_received()

    def _peer_closed(self) -> None:
        # The peer closed: we can no longer write either, as with a TCP connection torn down from one side.
        if not self._closing:
            self._closing = True
            self._connection_lost(None)

    def _connection_lost(self, exc: Exception | None) -> None:
        if not self._lost:
            self._lost = True
            self._protocol.connection_lost(exc)


def _end(loop: asyncio.AbstractEventLoop, chunk_size: int | None, name: str) -> tuple[StreamEnd, MemoryTransport]:
    reader = asyncio.StreamReader(loop=loop)
    protocol = asyncio.StreamReaderProtocol(reader, loop=loop)
    transport = MemoryTransport(loop, protocol, chunk_size=chunk_size, name=name)
    protocol.connection_made(transport)
    writer = asyncio.StreamWriter(transport, protocol, reader, loop)
    return (reader, writer), transport


def stream_pair(*, chunk_size: int | None = None, server_chunk_size: int | None = None) -> tuple[StreamEnd, StreamEnd]:
    """Two connected stream ends ``((reader, writer), (reader, writer))`` in the running loop.

    ``chunk_size`` fragments what the first end writes, ``server_chunk_size`` what the second end writes
    (``None``: each write arrives whole).
    """
    loop = asyncio.get_running_loop()
    a, ta = _end(loop, chunk_size, "memory-client")
    b, tb = _end(loop, server_chunk_size, "memory-server")
    ta.peer, tb.peer = tb, ta
    return a, b


Handler = Callable[[asyncio.StreamReader, asyncio.StreamWriter], Awaitable[None]]


class memory_connector:  # noqa: N801 - used like a function: RobotClient(connector=memory_connector(handler))
    """A ``RobotClient`` connector: each connect makes a :func:`stream_pair` and runs ``handler(reader, writer)``
    on the server end as a task owned by this object (``await connector.aclose()`` cancels and awaits them)."""

    def __init__(self, handler: Handler, *, chunk_size: int | None = None,
                 server_chunk_size: int | None = None) -> None:
        self._handler = handler
        self._chunk_size = chunk_size
        self._server_chunk_size = server_chunk_size
        self.tasks: list[asyncio.Task[None]] = []

    async def __call__(self) -> StreamEnd:
        client_end, server_end = stream_pair(chunk_size=self._chunk_size, server_chunk_size=self._server_chunk_size)
        self.tasks.append(asyncio.get_running_loop().create_task(self._handler(*server_end)))
        return client_end

    async def aclose(self) -> None:
        for t in self.tasks:
            t.cancel()
        for t in self.tasks:
            try:
                await t
            except asyncio.CancelledError:
                pass
            except Exception:  # a handler's failure was the test's business; closing must not mask it twice
                pass
        self.tasks.clear()
