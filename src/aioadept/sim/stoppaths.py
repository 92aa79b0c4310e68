"""The simulated server's two stop paths, the ways a ``stop`` reaches the controller when a client slot cannot
carry it (docs/protocol.md 4.2.1):

- the stop port: a second TCP port serving only ``stop``, ``here`` and ``hello``; each connection there is closed
  once it has had nothing pending for ``stop_window_s``;
- the reserved stop path: a connection over ``max_clients`` is not refused at once; for ``stop_window_s`` its
  ``stop`` lines are executed, anything else gets the SERVER_BUSY refusal and the close.

Both share a limit of ``max_stop_probes`` connections at once, the oldest without a stop evicted for a newcomer
(:func:`probe_to_evict`), so a newcomer always gets its window. The server
(:class:`~aioadept.sim.server.SimServer`) admits the connection and hands it here with the few things a stop path
needs of it (:class:`StopHost`); a stop read here goes to the controller the moment it is read, as on a client
connection.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Iterable
from typing import Any, Protocol

from aioadept.errors import RemoteProtocolError
from aioadept.geometry import Pose
from aioadept.protocol import (
    MAX_LINE, STOP_SKILL, Ack, CommandMessage, ErrorCode, LineFramer, encode_ack, parse_command,
)

__all__ = ["READ_SIZE", "STOP_PORT_SKILLS", "StopHost", "StopPaths", "parse_line", "probe_to_evict"]

READ_SIZE = 4096
"""Bytes taken from one connection per read: about a hundred command lines, so one flooding peer's turn is short."""
STOP_PORT_SKILLS = frozenset({STOP_SKILL, "here", "hello"})
"""What the stop port serves; any other skill is answered UNKNOWN_SKILL and nothing runs."""
AT_REST_WAIT_S = 30.0
"""The longest a stop path's connection stays open for the acks of its stops (a stop is at rest in well under a
second)."""


class StopHost(Protocol):
    """What a stop path needs of its server."""

    def now(self) -> float: ...
    def handle(self, item: bytes | CommandMessage, conn: Any, now: float) -> None: ...
    def reschedule(self) -> None: ...
    def pending(self, conn: Any) -> bool: ...
    def settled(self, conn: Any) -> bool: ...
    def refusal(self, text: str) -> bytes: ...
    def here(self) -> Pose: ...


def parse_line(item: object) -> CommandMessage | None:
    """The command a framed line carries, or None (an oversize line, or not a command)."""
    if isinstance(item, bytes):
        with contextlib.suppress(RemoteProtocolError):
            return parse_command(item)
    return None


def probe_to_evict(conns: Iterable[Any], max_probes: int) -> Any | None:
    """Of ``conns`` (oldest first), the stop-path connection to close so a newcomer fits within ``max_probes``:
    the oldest that has not sent a stop (one carrying a stop is never evicted); None when there is room."""
    probes = [c for c in conns if c.limited]
    if len(probes) < max_probes:
        return None
    return next((c for c in probes if not c.stopped), None)


class _NotAStop(Exception):
    """A connection on the reserved stop path sent something other than stop."""


class StopPaths:
    """Serves the connections of both stop paths of ``host``; ``window_s``: the server's ``stop_window_s``."""

    def __init__(self, host: StopHost, window_s: float) -> None:
        self.host = host
        self.window_s = window_s

    def make_room(self, conns: Iterable[Any], max_probes: int) -> None:
        """Before a newcomer joins a stop path: evict the oldest connection without a stop if the paths are full."""
        victim = probe_to_evict(conns, max_probes)
        if victim is not None:
            with contextlib.suppress(OSError):
                victim.writer.write(self.host.refusal("too many clients"))
            victim.writer.transport.abort()

    async def serve_probe(self, conn: Any, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """A connection over ``max_clients``: within the window its ``stop`` lines are executed; anything else, or
        the end of the window, answers the SERVER_BUSY refusal (ID 00000000) and closes. The connection stays
        until its stops are acked."""
        host = self.host
        framer = LineFramer(MAX_LINE)
        loop = asyncio.get_running_loop()
        refuse = True  # unless the peer closed first, or sent only stops
        try:
            async with asyncio.timeout_at(loop.time() + self.window_s):
                while True:
                    data = await reader.read(READ_SIZE)
                    if not data:
                        refuse = False
                        break
                    now = host.now()
                    for item in framer.feed(data):
                        msg = parse_line(item)
                        if msg is None or msg.skill != STOP_SKILL:
                            raise _NotAStop
                        conn.stopped = True
                        conn.messages += 1
                        host.handle(msg, conn, now)
                    host.reschedule()
        except TimeoutError:
            refuse = not conn.stopped  # the window ended: a peer that sent stops gets their acks, no refusal
        except _NotAStop:
            pass
        if conn.stopped and host.pending(conn):
            await self._wait_idle(conn)
        if refuse and not writer.is_closing():
            with contextlib.suppress(OSError):
                writer.write(host.refusal("too many clients; only stop is served"))
                await writer.drain()

    async def serve_port(self, conn: Any, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """A connection to the stop port: ``stop``, ``here`` and ``hello`` go to the controller (a stop acts the
        moment it is read); any other line answers UNKNOWN_SKILL and nothing runs. The connection is closed once
        it has had nothing pending for the window (from its connect or its last line), so idle or trickling peers
        cannot keep the port from the next stop; the vplus server does the same (rs.stmo)."""
        host = self.host
        framer = LineFramer(MAX_LINE)
        loop = asyncio.get_running_loop()
        last = loop.time()
        while True:
            try:
                async with asyncio.timeout_at(last + self.window_s):
                    data = await reader.read(READ_SIZE)
            except TimeoutError:
                if not host.settled(conn):  # a stop is still coming to rest: close after its ack
                    await self._wait_idle(conn)
                return
            if not data:
                return
            now = host.now()
            for item in framer.feed(data):
                msg = parse_line(item)
                if msg is not None and msg.skill not in STOP_PORT_SKILLS:
                    ack = Ack.error(msg.id, ErrorCode.UNKNOWN_SKILL, "the stop port serves stop, here and hello only",
                                    now, now, host.here())
                    writer.write(encode_ack(ack))
                    continue
                if msg is not None and msg.skill == STOP_SKILL:
                    conn.stopped = True
                    conn.stop_ids.add(msg.id)
                conn.messages += 1
                host.handle(item if msg is None else msg, conn, now)
            host.reschedule()
            await writer.drain()
            last = loop.time()

    @staticmethod
    async def _wait_idle(conn: Any) -> None:
        """Until the server sets ``conn.idle`` (its last pending ack written), at most :data:`AT_REST_WAIT_S`."""
        conn.idle = asyncio.Event()
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(AT_REST_WAIT_S):
                await conn.idle.wait()
