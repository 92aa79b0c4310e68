"""A bare asyncio TCP server on 127.0.0.1 for tests that play a controller by hand (test_client_tcp.py,
test_client_stop_path.py, test_cell_bus_nodes.py): one place for starting it on a free port and for ending its
connections when the test is done."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Awaitable, Callable


@contextlib.asynccontextmanager
async def raw_server(handler: Callable[[asyncio.StreamReader, asyncio.StreamWriter], Awaitable[None]]
                     ) -> AsyncIterator[int]:
    """Serve ``handler(reader, writer)`` on each connection to 127.0.0.1:PORT; yields PORT. A peer that goes away
    ends its handler quietly; on leaving, the server closes and handlers still running are cancelled."""
    tasks: set[asyncio.Task] = set()

    async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        tasks.add(task)
        try:
            await handler(reader, writer)
        except (ConnectionError, asyncio.CancelledError):
            pass
        finally:
            writer.close()
            tasks.discard(task)

    server = await asyncio.start_server(serve, "127.0.0.1", 0)
    try:
        yield server.sockets[0].getsockname()[1]
    finally:
        server.close()
        for t in list(tasks):
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
