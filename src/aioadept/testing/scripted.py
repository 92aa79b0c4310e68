"""ScriptedServer: a robot-server double that acks per a script, over real TCP (or in memory), for tests.

It speaks the line protocol through the same sans-IO core as everything else, but its behaviour is whatever the
test says, message by message: ``done`` / ``error`` / ``aborted``, a delay, silence (never ack), or dropping the
connection. It records what it saw, so tests can assert what went over the wire::

    script = {"move_to": Reply(delay_s=0.05), "bad": Reply.error(-406, "undefined skill")}
    async with ScriptedServer(script) as server:                 # 127.0.0.1, port 0
        async with RobotClient(server.host, server.port) as robot:
            await robot.cmdexec(MoveTo([...]))
        assert server.lines() == [b"....:move_to:...", b"....:break"]

Like the real server it reads independently of executing: messages are queued on arrival and run one at a time in
arrival order, and a ``stop`` line is handled the moment it is read (the executing and queued messages are acked
``aborted``, then the stop ``done``), as docs/protocol.md specifies.
"""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Union

from aioadept.errors import RemoteProtocolError
from aioadept.geometry import Pose
from aioadept.protocol import (
    HELLO_SKILL,
    MAX_LINE,
    PROTOCOL_VERSION,
    STOP_SKILL,
    Ack,
    CommandMessage,
    ErrorCode,
    LineFramer,
    Oversize,
    Status,
    encode_ack,
    parse_command,
    recover_id,
)
from aioadept.testing.streams import StreamEnd, stream_pair

__all__ = ["Connection", "Event", "Reply", "ScriptedServer"]


@dataclass(frozen=True, slots=True)
class Reply:
    """What the server does with one message.

    ``status``: done/error/aborted; ``delay_s``: time the "skill" takes before the ack (a stop cuts it short);
    ``silent``: never ack; ``drop``: close the connection instead of acking (``reset=True``: abort it);
    ``pose``: the ack's pose (default: the server's current pose); ``extra``: trailing ack fields.
    """

    status: Status = Status.DONE
    delay_s: float = 0.0
    silent: bool = False
    drop: bool = False
    reset: bool = False
    pose: Pose | None = None
    extra: tuple[str, ...] = ()

    @classmethod
    def error(cls, code: int = ErrorCode.SKILL_FAILED, message: str = "skill failed", **kw: Any) -> Reply:
        return cls(status=Status.ERROR, extra=(str(int(code)), message), **kw)

    @classmethod
    def aborted(cls, **kw: Any) -> Reply:
        return cls(status=Status.ABORTED, **kw)


DONE = Reply()

Script = Union[
    Callable[[CommandMessage, int], "Reply | None"],
    Mapping[str, Reply],
    Sequence[Reply],
    None,
]
"""A callable ``(message, index) -> Reply`` (index counts messages on the server, from 0), a mapping skill name ->
Reply, or a sequence of Replies by index. Anything not covered is acked ``done`` at once."""


@dataclass(frozen=True, slots=True)
class Event:
    """One thing the server saw or did, with its loop-clock time: kind is ``recv``, ``ack``, ``drop`` or ``bad``."""

    kind: str
    id: str
    t_s: float
    line: bytes = b""
    status: str = ""


@dataclass(slots=True)
class Connection:
    """What happened on one accepted connection."""

    index: int
    chunks: list[bytes] = field(default_factory=list)
    """Every read as it came off the socket (shows how writes were split/coalesced)."""
    events: list[Event] = field(default_factory=list)
    closed: asyncio.Event = field(default_factory=asyncio.Event)

    def lines(self) -> list[bytes]:
        return [e.line for e in self.events if e.kind == "recv"]

    def ids(self, kind: str = "recv") -> list[str]:
        return [e.id for e in self.events if e.kind == kind]


class ScriptedServer:
    """A scripted robot server on ``host``:``port`` (port 0: any free port; read ``server.port`` after start).

    ``drop_after=N`` drops the connection instead of acking the N-th message of a connection (counting from 1;
    ``stop`` lines do not count); ``silent_after=N`` acks nothing from a connection's N-th message on. ``pose`` is the pose in acks. Use as ``async with``,
    or ``await start()`` / ``await close()``; ``connector()`` serves in memory instead (for RobotClient).
    """

    def __init__(self, script: Script = None, *, host: str = "127.0.0.1", port: int = 0,
                 drop_after: int | None = None, silent_after: int | None = None,
                 pose: Pose = Pose(300.0, 0.0, 500.0, 0.0, 180.0, 0.0), max_line: int = MAX_LINE,
                 server_name: str = "aioadept-scripted") -> None:
        self.script = script
        self.host = host
        self.port = port
        self.drop_after = drop_after
        self.silent_after = silent_after
        self.pose = pose
        self.max_line = max_line
        self.server_name = server_name
        self.connections: list[Connection] = []
        self._server: asyncio.Server | None = None
        self._tasks: set[asyncio.Task[None]] = set()
        self._serving: set[asyncio.Task[None]] = set()
        self._count = itertools.count()
        self._t0 = 0.0
        self._connected = asyncio.Condition()

    # --- lifecycle
    async def start(self) -> ScriptedServer:
        loop = asyncio.get_running_loop()
        self._t0 = loop.time()
        self._server = await asyncio.start_server(self._serve, self.host, self.port)
        self.port = self._server.sockets[0].getsockname()[1]
        return self

    async def close(self) -> None:
        """Stop listening, cancel every connection task and await it."""
        if self._server is not None:
            self._server.close()
            # Connections accepted just before have their handler task scheduled but not started; one loop turn
            # lets them register, so they are cancelled and closed below instead of being left open.
            await asyncio.sleep(0)
        tasks = list(self._tasks)
        for t in tasks:
            t.cancel()
        for t in [*tasks, *self._serving]:
            try:
                await t
            except (asyncio.CancelledError, Exception):
                pass
        if self._server is not None:
            await self._server.wait_closed()
            self._server = None

    async def __aenter__(self) -> ScriptedServer:
        return await self.start()

    async def __aexit__(self, *exc: Any) -> None:
        await self.close()

    def connector(self, *, chunk_size: int | None = None, server_chunk_size: int | None = None):  # noqa: ANN201
        """A RobotClient ``connector`` that serves this script over an in-memory stream pair (no socket)."""
        async def connect() -> StreamEnd:
            if not self._t0:
                self._t0 = asyncio.get_running_loop().time()
            client_end, server_end = stream_pair(chunk_size=chunk_size, server_chunk_size=server_chunk_size)
            self._spawn(self._handle(*server_end))
            return client_end
        return connect

    # --- inspection
    def lines(self) -> list[bytes]:
        """Every command line received, over all connections, in order."""
        return [line for c in self.connections for line in c.lines()]

    async def wait_connections(self, n: int) -> Connection:
        """Wait until ``n`` connections were accepted; return the n-th."""
        async with self._connected:
            await self._connected.wait_for(lambda: len(self.connections) >= n)
        return self.connections[n - 1]

    # --- serving
    def _spawn(self, coro: Any) -> None:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        # asyncio's start_server owns this task and (3.11) logs an error if it ends cancelled, so the connection
        # runs in an inner task that close() cancels, and this one returns normally.
        outer = asyncio.current_task()
        assert outer is not None
        self._serving.add(outer)
        inner = asyncio.get_running_loop().create_task(self._handle(reader, writer))
        self._tasks.add(inner)
        inner.add_done_callback(self._tasks.discard)
        try:
            await inner
        except asyncio.CancelledError:
            if not inner.cancelled() or outer.cancelling():
                raise
        finally:
            self._serving.discard(outer)
            if not writer.is_closing():  # the inner task was cancelled before it ran: close here instead
                writer.close()

    def _reply_for(self, msg: CommandMessage, index: int, conn_count: int) -> Reply:
        if self.drop_after is not None and conn_count >= self.drop_after:
            return Reply(drop=True)
        if self.silent_after is not None and conn_count >= self.silent_after:
            return Reply(silent=True)
        script = self.script
        reply: Reply | None
        if script is None:
            reply = None
        elif callable(script):
            reply = script(msg, index)
        elif isinstance(script, Mapping):
            reply = script.get(msg.skill)
        else:
            reply = script[index] if index < len(script) else None
        return reply or DONE

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        loop = asyncio.get_running_loop()
        conn = Connection(len(self.connections))
        self.connections.append(conn)
        async with self._connected:
            self._connected.notify_all()
        queue: asyncio.Queue[tuple[CommandMessage, Reply]] = asyncio.Queue()
        state: dict[str, Any] = {"current": None, "dropped": False}

        def now() -> float:
            return loop.time()

        def ack(mid: str, status: Status, extra: tuple[str, ...] = (), pose: Pose | None = None,
                t_start: float | None = None) -> None:
            if state["dropped"] or writer.is_closing():
                return
            t = now() - self._t0
            a = Ack(mid, status, t if t_start is None else t_start, t, pose or self.pose, extra)
            writer.write(encode_ack(a))
            conn.events.append(Event("ack", mid, now(), status=status.value))

        async def execute() -> None:
            while True:
                msg, reply = await queue.get()
                if reply.drop:
                    conn.events.append(Event("drop", msg.id, now()))
                    state["dropped"] = True
                    _hang_up(writer, reply.reset)
                    return
                if reply.silent:
                    continue
                t_start = now() - self._t0
                if reply.delay_s > 0:
                    state["current"] = msg.id
                    try:
                        await asyncio.sleep(reply.delay_s)  # the simulated skill's duration, not a readiness wait
                    finally:
                        state["current"] = None
                ack(msg.id, reply.status, self._extra(msg, reply), reply.pose, t_start)

        executor = loop.create_task(execute())
        framer = LineFramer(max_line=self.max_line)
        conn_count = 0
        try:
            while not state["dropped"]:
                try:
                    data = await reader.read(65536)
                except (ConnectionError, OSError):
                    break
                if not data:
                    break
                conn.chunks.append(data)
                for item in framer.feed(data):
                    msg = self._parsed(item, conn, writer, now())
                    if msg is None:
                        continue
                    if msg.skill == STOP_SKILL:
                        executor = await self._stop(executor, queue, state, ack, msg, execute, loop)
                        continue
                    conn_count += 1
                    queue.put_nowait((msg, self._reply_for(msg, next(self._count), conn_count)))
        finally:
            await self._close(executor, writer, conn)

    def _extra(self, msg: CommandMessage, reply: Reply) -> tuple[str, ...]:
        """The ack's extra fields: the script's, else a hello's version and server name."""
        if msg.skill == HELLO_SKILL and not reply.extra:
            return (str(PROTOCOL_VERSION), self.server_name)
        return reply.extra

    def _parsed(self, item: bytes | Oversize, conn: Connection, writer: asyncio.StreamWriter,
                now: float) -> CommandMessage | None:
        """The command of a line, recorded as received; None for a line refused with its error ack."""
        if isinstance(item, Oversize):
            conn.events.append(Event("bad", "", now, item.head))
            writer.write(encode_ack(Ack.error(recover_id(item.head), ErrorCode.LINE_TOO_LONG, None, 0.0, 0.0,
                                              self.pose)))
            return None
        try:
            msg = parse_command(item)
        except RemoteProtocolError as exc:
            conn.events.append(Event("bad", exc.id or "", now, item))
            writer.write(encode_ack(Ack.error(exc.id, exc.code, exc.message, 0.0, 0.0, self.pose)))
            return None
        conn.events.append(Event("recv", msg.id, now, item))
        return msg

    @staticmethod
    async def _close(executor: asyncio.Task[None], writer: asyncio.StreamWriter, conn: Connection) -> None:
        executor.cancel()
        try:
            await executor
        except (asyncio.CancelledError, Exception):
            pass
        if not writer.is_closing():
            writer.close()
        try:
            await writer.wait_closed()
        except (ConnectionError, OSError):
            pass
        conn.closed.set()

    async def _stop(self, executor: asyncio.Task[None], queue: asyncio.Queue, state: dict[str, Any], ack: Any,
                    msg: CommandMessage, execute: Any, loop: asyncio.AbstractEventLoop) -> asyncio.Task[None]:
        # Abort what is executing (its delay is cut short), flush the queue with `aborted`, ack the stop `done`.
        current = state["current"]
        executor.cancel()
        try:
            await executor
        except asyncio.CancelledError:
            pass
        if current is not None:
            ack(current, Status.ABORTED)
        while not queue.empty():
            queued, _reply = queue.get_nowait()
            ack(queued.id, Status.ABORTED)
        ack(msg.id, Status.DONE)
        return loop.create_task(execute())


def _hang_up(writer: asyncio.StreamWriter, reset: bool) -> None:
    """Close the connection: with an RST (``reset``) or an orderly FIN."""
    if reset:
        writer.transport.abort()
    else:
        writer.close()
