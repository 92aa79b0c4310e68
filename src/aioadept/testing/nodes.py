"""``running_node()``: an aioadept node (``sim``, ``vision``, ...) as a real child process, for tests.

    async with running_node("sim", "--port", "0", log_path=tmp_path / "sim.log") as node:
        port = int(node.ready["port"])      # the fields of its READY line
        node.proc                           # the asyncio subprocess

It waits for the node's READY line (never a sleep), keeps its output in ``log_path``, and on exit stops it
(SIGINT, then SIGTERM, then SIGKILL) and, with ``expect_clean_exit``, checks that it exited with 0.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from aioadept.apps.processes import NodeProcess

__all__ = ["running_node"]


@asynccontextmanager
async def running_node(command: str, *args: str, log_path: Path | None = None, ready_timeout_s: float = 30.0,
                       expect_clean_exit: bool = True) -> AsyncIterator[NodeProcess]:
    """Start ``python -m aioadept COMMAND ARGS...``; yield the :class:`NodeProcess` once it is READY."""
    node = NodeProcess(command, [command, *args], log_path=log_path, ready_timeout_s=ready_timeout_s)
    await node.start()
    try:
        yield node
    finally:
        code = await node.stop()
    if expect_clean_exit and code not in (0, None):
        raise AssertionError(f"{command} exited with {code}:\n{node.tail()}")
