"""A TCP relay that forwards every byte in a write of its own, both ways: 1-byte fragmentation on a real socket.

    async with ChopRelay(sim.host, sim.port) as relay:      # client -> relay.port -> sim, and back
        RobotClient(relay.host, relay.port)

Each byte is written with its own ``send()`` (asyncio sets TCP_NODELAY, so Nagle does not glue them), and the relay
yields to the loop between bytes so the receiver gets the chance to read them one by one. ``writes`` counts the
single-byte writes per direction, so a test can check that fragmentation really happened.
"""

from __future__ import annotations

import asyncio
import contextlib


class ChopRelay:
    def __init__(self, target_host: str, target_port: int, *, chunk: int = 1) -> None:
        self.target = (target_host, target_port)
        self.chunk = chunk
        self.host = "127.0.0.1"
        self.port = 0
        self.writes = {"up": 0, "down": 0}
        self._server: asyncio.base_events.Server | None = None
        self._tasks: set[asyncio.Task[None]] = set()
        self._writers: list[asyncio.StreamWriter] = []

    async def __aenter__(self) -> ChopRelay:
        self._server = await asyncio.start_server(self._accept, self.host, 0)
        self.port = self._server.sockets[0].getsockname()[1]
        return self

    async def __aexit__(self, *exc: object) -> None:
        assert self._server is not None
        self._server.close()
        for w in self._writers:
            w.transport.abort()
        for t in list(self._tasks):
            t.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        await self._server.wait_closed()

    async def _accept(self, c_reader: asyncio.StreamReader, c_writer: asyncio.StreamWriter) -> None:
        s_reader, s_writer = await asyncio.open_connection(*self.target)
        self._writers += [c_writer, s_writer]
        up = asyncio.create_task(self._pump(c_reader, s_writer, "up"))
        down = asyncio.create_task(self._pump(s_reader, c_writer, "down"))
        self._tasks |= {up, down}
        # Either side closing ends both: the relay must not keep a half of a dead connection alive.
        await asyncio.wait({up, down}, return_when=asyncio.FIRST_COMPLETED)
        for w in (c_writer, s_writer):
            w.close()
        await asyncio.gather(up, down, return_exceptions=True)
        self._tasks -= {up, down}

    async def _pump(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, direction: str) -> None:
        with contextlib.suppress(ConnectionError, OSError):
            while data := await reader.read(65536):
                for i in range(0, len(data), self.chunk):
                    writer.write(data[i:i + self.chunk])
                    self.writes[direction] += 1
                    await writer.drain()
                    await asyncio.sleep(0)
