"""RobotClient: the asyncio side of the robot line protocol (the paper's MasterControlNode ↔ RobotServer link).

It sits between the commands (:mod:`aioadept.commands`, values that expand to skill calls) and the TCP stream, and
drives the sans-IO core (:mod:`aioadept.protocol`) over asyncio streams::

    async with RobotClient("127.0.0.1", 1234) as robot:
        await robot.cmdexec(MoveJoints([0, -90, 180, 0, 90, 0]))          # one command at a time
        res = await robot.cmdexec_joined(SetSpeed(20), MoveToolZ(2.5))     # all messages in one write
        print(res.pose, res.messages[-1].t_recv_s - res.messages[0].t_send_s)

How it works, and the promises it keeps:

- One write path (:meth:`RobotClient._send`): IDs are allocated, a future per message is registered in the pending
  registry *before* the bytes are written, then the batch goes out in one ``write``.
- One reader task routes acks to futures by ID. It owns no other work, so the ack path stays short: no per-message
  logging, no per-message task.
- Every waiter removes its messages from the registry in ``finally``; an ack that arrives later for a cancelled or
  timed-out message is dropped quietly and counted (:attr:`ClientStats.late_acks`).
- Nothing is ever re-sent. When the connection drops, every pending future fails with :class:`ConnectionLost`,
  whose ``acked`` / ``unresolved`` say what is known done and what may or may not have run on the robot.
  Reconnecting is an explicit :meth:`connect` (or the opt-in ``auto_reconnect=True``, which reconnects before the
  *next* new command and still re-sends nothing).
- Observers (``on_send`` / ``on_ack``, see docs/interfaces.md) get loop-clock timestamps taken at write and read.
"""

from __future__ import annotations

import asyncio
import enum
import logging
import secrets
import socket
from collections import deque
from collections.abc import Awaitable, Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from aioadept.commands import Command
from aioadept.errors import (
    AckTimeout,
    ClientStateError,
    CommandAborted,
    CommandError,
    ConnectError,
    ConnectionLost,
    RemoteProtocolError,
)
from aioadept.geometry import Pose
from aioadept.protocol import (
    HELLO_SKILL,
    HERE_SKILL,
    MAX_ACK_LINE,
    NO_ID,
    STOP_SKILL,
    Ack,
    IdAllocator,
    LineFramer,
    Oversize,
    SkillCall,
    Status,
    parse_ack,
)

__all__ = [
    "ClientState", "ClientStats", "CommandResult", "Connector", "ExecResult", "MessageResult", "Observer",
    "RobotClient", "SentMessage", "Submission",
]

log = logging.getLogger(__name__)

Connector = Callable[[], Awaitable[tuple[asyncio.StreamReader, asyncio.StreamWriter]]]
"""An async callable that opens a (reader, writer) pair; the default opens TCP to ``host:port``."""

_READ_SIZE = 1 << 16
_ABANDONED_MEMORY = 4096  # how many cancelled/timed-out IDs we remember to tell late acks from unknown ones
_UNEXPECTED_MEMORY = 100


# ---------------------------------------------------------------------------------------------------- values
@dataclass(frozen=True, slots=True)
class SentMessage:
    """One command message as written (observer ``on_send``). ``t_send_s`` is ``loop.time()`` at the write."""

    id: str
    skill: str
    args: tuple
    batch: int
    t_send_s: float


@dataclass(frozen=True, slots=True)
class MessageResult:
    """One command message and its ack (observer ``on_ack``; element of every result).

    ``t_send_s`` / ``t_recv_s`` are client loop-clock seconds at the write and at the read that delivered the ack;
    the ack's ``t_start_s`` / ``t_done_s`` are server-clock seconds.
    """

    id: str
    skill: str
    args: tuple
    batch: int
    t_send_s: float
    t_recv_s: float
    ack: Ack

    @property
    def status(self) -> Status:
        return self.ack.status

    @property
    def ok(self) -> bool:
        return self.ack.status is Status.DONE

    @property
    def pose(self) -> Pose:
        return self.ack.pose

    @property
    def rtt_s(self) -> float:
        """Client round trip: read time minus write time (seconds)."""
        return self.t_recv_s - self.t_send_s


@dataclass(frozen=True, slots=True)
class CommandResult:
    """The messages of one command, in the order they were sent."""

    command: Command | None
    messages: tuple[MessageResult, ...]

    @property
    def pose(self) -> Pose:
        """The pose in the last ack (for a motion with break: where the robot came to rest)."""
        return self.messages[-1].ack.pose


@dataclass(frozen=True, slots=True)
class ExecResult:
    """What :meth:`RobotClient.cmdexec` / :meth:`RobotClient.cmdexec_joined` return: per command, per message."""

    commands: tuple[CommandResult, ...]

    @property
    def messages(self) -> tuple[MessageResult, ...]:
        """All messages of all commands, in send order."""
        return tuple(m for c in self.commands for m in c.messages)

    @property
    def pose(self) -> Pose:
        """The pose in the last ack."""
        return self.commands[-1].messages[-1].ack.pose

    def __iter__(self) -> Iterator[MessageResult]:
        return iter(self.messages)

    def __len__(self) -> int:
        return sum(len(c.messages) for c in self.commands)


class ClientState(str, enum.Enum):
    NEW = "new"
    CONNECTED = "connected"
    LOST = "lost"          # the peer closed or the socket failed; connect() again to go on
    CLOSED = "closed"      # close() was called; connect() again to reuse


@dataclass(slots=True)
class ClientStats:
    """Counters of the unusual; all zero on a healthy connection except ``acks``/``messages_sent``."""

    messages_sent: int = 0
    acks: int = 0
    late_acks: int = 0
    """Acks for messages whose waiter was cancelled or timed out (dropped quietly)."""
    unknown_acks: int = 0
    """Acks whose ID was never pending here."""
    unroutable_errors: int = 0
    """``error`` acks with ID ``00000000``: the server could not read an ID from a line we sent."""
    bad_lines: int = 0
    """Lines from the server that do not parse as acks (or are over the length limit)."""
    unexpected: deque = field(default_factory=lambda: deque(maxlen=_UNEXPECTED_MEMORY))
    """The most recent unknown/unroutable/bad lines, as ``(loop_time_s, kind, bytes)``."""


class Observer(Protocol):
    def on_send(self, msg: SentMessage) -> None: ...
    def on_ack(self, result: MessageResult) -> None: ...


# ------------------------------------------------------------------------------------------------ submission
class Submission:
    """Handle of one :meth:`RobotClient.submit`: the IDs written together and a future per message.

    Each future resolves to a :class:`MessageResult` whatever the ack's status (so an ignored future never logs
    "exception never retrieved"), or fails with :class:`ConnectionLost`. :meth:`wait` turns statuses into errors
    and removes the messages from the client's registry; call it (or :meth:`cancel`) exactly once.
    """

    __slots__ = ("_client", "ids", "calls", "batch", "futures", "_settled")

    def __init__(self, client: RobotClient, ids: tuple[str, ...], calls: tuple[SkillCall, ...], batch: int,
                 futures: tuple[asyncio.Future[MessageResult], ...]) -> None:
        self._client = client
        self.ids = ids
        self.calls = calls
        self.batch = batch
        self.futures = futures
        self._settled = False

    def done(self) -> bool:
        return all(f.done() for f in self.futures)

    async def wait(self, *, timeout_s: float | None = None) -> tuple[MessageResult, ...]:
        """All results in send order. Raises CommandError / CommandAborted (first failing message, after all
        acks are in; ``exc.results`` holds them), ConnectionLost, or AckTimeout (``timeout_s=None``: the client's
        ``ack_timeout_s``)."""
        return await self._client._wait(self, timeout_s)

    def cancel(self) -> None:
        """Stop waiting: forget the messages (late acks are dropped and counted). The robot is not stopped."""
        self._client._release(self)

    def __repr__(self) -> str:
        done = sum(f.done() for f in self.futures)
        return f"<Submission batch={self.batch} ids={list(self.ids)} done={done}/{len(self.futures)}>"


# ---------------------------------------------------------------------------------------------------- client
class RobotClient:
    """An asyncio client of a RobotServer (the V+ AdeptServer, or ``aioadept sim``).

    Reusable (``connect`` again after ``close`` or a lost connection), not reentrant. Options:

    - ``connect_timeout_s``: limit of :meth:`connect` (→ :class:`ConnectError`).
    - ``ack_timeout_s``: default limit of every wait for acks (→ :class:`AckTimeout`); ``None`` waits forever.
      A break waits for the whole motion, so keep this above your longest motion.
    - ``observers``: objects with ``on_send(SentMessage)`` / ``on_ack(MessageResult)``.
    - ``id_start``: first message ID as an int (IDs count up from a random start by default).
    - ``auto_reconnect``: after a lost connection, reconnect before the next new command. Never re-sends.
    - ``connector``: an async callable returning ``(reader, writer)``, to run over other streams (e.g.
      :func:`aioadept.testing.memory_connector`); ``host``/``port`` are then only used in messages.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 1234, *, connect_timeout_s: float = 5.0,
                 ack_timeout_s: float | None = 60.0, observers: Iterable[Observer] = (),
                 id_start: int | None = None, auto_reconnect: bool = False,
                 connector: Connector | None = None, max_line: int = MAX_ACK_LINE) -> None:
        self.host = host
        self.port = port
        self.connect_timeout_s = connect_timeout_s
        self.ack_timeout_s = ack_timeout_s
        self.auto_reconnect = auto_reconnect
        self._connector = connector
        self._observers: list[Observer] = list(observers)
        self._ids = IdAllocator(secrets.randbits(32) if id_start is None else id_start)
        self._framer = LineFramer(max_line=max_line)
        # id -> (future, call, batch, t_send_s). The one registry of pending messages.
        self._pending: dict[str, tuple[asyncio.Future[MessageResult], SkillCall, int, float]] = {}
        # IDs given up by their waiter (cancel/timeout), to count their late acks; dict as an ordered set.
        self._abandoned: dict[str, None] = {}
        self._acked_since_connect: int = 0
        self._batch = 0
        self._state = ClientState.NEW
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None
        self._reader_task: asyncio.Task[None] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._lost_reason: BaseException | None = None
        self._in_context = False
        self._connect_lock: asyncio.Lock | None = None
        self.stats = ClientStats()

    # ------------------------------------------------------------------------------------------- lifecycle
    @property
    def state(self) -> ClientState:
        return self._state

    @property
    def connected(self) -> bool:
        return self._state is ClientState.CONNECTED

    @property
    def pending_ids(self) -> tuple[str, ...]:
        """IDs written and not yet acked (nor given up)."""
        return tuple(self._pending)

    def add_observer(self, observer: Observer) -> None:
        self._observers.append(observer)

    def remove_observer(self, observer: Observer) -> None:
        self._observers.remove(observer)

    async def __aenter__(self) -> RobotClient:
        if self._in_context:
            raise ClientStateError("RobotClient is not reentrant: already inside 'async with'")
        self._in_context = True
        try:
            await self.connect()
        except BaseException:
            self._in_context = False
            raise
        return self

    async def __aexit__(self, *exc_info: Any) -> None:
        try:
            await self.close()
        finally:
            self._in_context = False

    async def connect(self) -> None:
        """Open the connection and start the reader. Raises ConnectError, or ClientStateError if connected."""
        if self._state is ClientState.CONNECTED:
            raise ClientStateError(f"already connected to {self.host}:{self.port}")
        await self._teardown()  # a lost connection's reader task and writer, if any
        loop = asyncio.get_running_loop()
        try:
            async with asyncio.timeout(self.connect_timeout_s):
                if self._connector is not None:
                    reader, writer = await self._connector()
                else:
                    reader, writer = await asyncio.open_connection(self.host, self.port)
        except TimeoutError:
            raise ConnectError(f"connect to {self.host}:{self.port}: no answer in {self.connect_timeout_s} s") \
                from None
        except OSError as exc:
            raise ConnectError(f"connect to {self.host}:{self.port}: {exc}") from exc
        sock = writer.get_extra_info("socket")
        if sock is not None:
            try:  # small writes must leave at once (asyncio sets this too; uvloop may not)
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            except (OSError, AttributeError):
                pass
        self._loop = loop
        self._reader, self._writer = reader, writer
        self._framer.reset()
        self._lost_reason = None
        self._acked_since_connect = 0
        self._state = ClientState.CONNECTED
        self._reader_task = loop.create_task(self._read_loop(reader), name=f"RobotClient reader {self.host}")

    async def close(self) -> None:
        """Close the connection; pending futures fail with ConnectionLost. Idempotent."""
        was = self._state
        self._state = ClientState.CLOSED
        if was is ClientState.CONNECTED:
            self._fail_pending("client closed the connection")
        await self._teardown()

    async def _teardown(self) -> None:
        task, writer = self._reader_task, self._writer
        self._reader_task = None
        self._writer = None
        self._reader = None
        if task is not None and not task.done():
            task.cancel()
        if writer is not None:
            writer.close()
        if task is not None:
            try:
                await task
            except asyncio.CancelledError:
                # Our own cancel of the reader; but if *we* are being cancelled, let that through.
                current = asyncio.current_task()
                if current is not None and current.cancelling():
                    raise
        if writer is not None:
            try:
                await writer.wait_closed()
            except (OSError, ConnectionError):
                pass

    # ------------------------------------------------------------------------------------------- reading
    async def _read_loop(self, reader: asyncio.StreamReader) -> None:
        """The only reader: cut the stream into lines and route each ack to its future."""
        feed = self._framer.feed
        route = self._route
        loop_time = asyncio.get_running_loop().time
        reason: BaseException | None = None
        try:
            while True:
                data = await reader.read(_READ_SIZE)
                if not data:
                    break
                t_recv = loop_time()
                for item in feed(data):
                    route(item, t_recv)
        except (OSError, ConnectionError) as exc:
            reason = exc
        except Exception as exc:  # a bug here must not leave waiters hanging forever
            log.exception("RobotClient reader failed")
            reason = exc
        # CancelledError (close/teardown) propagates: close() fails pending futures itself.
        self._on_lost(reason)

    def _route(self, item: bytes | Oversize, t_recv: float) -> None:
        if type(item) is not bytes:
            self._unexpected("oversize", item.head, t_recv)  # type: ignore[union-attr]
            return
        try:
            ack = parse_ack(item)
        except RemoteProtocolError:
            self._unexpected("bad_line", item, t_recv)
            return
        entry = self._pending.pop(ack.id, None)
        if entry is None:
            self._unmatched(ack, item, t_recv)
            return
        self.stats.acks += 1
        self._acked_since_connect += 1
        fut, call, batch, t_send = entry
        result = MessageResult(ack.id, call.skill, call.args, batch, t_send, t_recv, ack)
        if not fut.done():
            fut.set_result(result)
        if self._observers:
            self._notify_ack(result)

    def _unmatched(self, ack: Ack, line: bytes, t_recv: float) -> None:
        if ack.id in self._abandoned:
            del self._abandoned[ack.id]
            self.stats.late_acks += 1
        elif ack.id == NO_ID:
            self._unexpected("unroutable_error", line, t_recv)
        else:
            self._unexpected("unknown_ack", line, t_recv)

    def _unexpected(self, kind: str, line: bytes, t_recv: float) -> None:
        stats = self.stats
        if kind == "unknown_ack":
            stats.unknown_acks += 1
        elif kind == "unroutable_error":
            stats.unroutable_errors += 1
        else:
            stats.bad_lines += 1
        stats.unexpected.append((t_recv, kind, bytes(line)))
        log.warning("robot server %s:%s sent %s: %r", self.host, self.port, kind.replace("_", " "), line[:80])

    def _on_lost(self, reason: BaseException | None) -> None:
        if self._state is not ClientState.CONNECTED:
            return
        self._state = ClientState.LOST
        self._lost_reason = reason
        why = f"connection to {self.host}:{self.port} lost" + (f": {reason}" if reason else " (closed by peer)")
        log.warning("%s with %d message(s) unacked", why, len(self._pending))
        self._fail_pending(why)

    def _fail_pending(self, why: str) -> None:
        pending, self._pending = self._pending, {}
        for mid, (fut, _call, _batch, _t) in pending.items():
            if not fut.done():
                # Per message; the waiter (_wait) merges them into one error with the whole batch's sets.
                fut.set_exception(_lost(why, unresolved=(mid,)))

    # ------------------------------------------------------------------------------------------- writing
    def _send(self, calls: Sequence[SkillCall]) -> Submission:
        """The one write path: allocate IDs, register futures, then write the batch in one call."""
        if self._state is not ClientState.CONNECTED:
            self._raise_not_connected()
        loop = self._loop
        assert loop is not None and self._writer is not None
        self._batch += 1
        batch = self._batch
        new_id = self._ids.next
        pending = self._pending
        ids = []
        futs = []
        parts = []
        entries = []
        for call in calls:
            mid = new_id()
            fut = loop.create_future()
            ids.append(mid)
            futs.append(fut)
            parts.append(f"{mid}:{call.wire}\r\n")
            entries.append((mid, fut, call))
        data = "".join(parts).encode("ascii")
        t_send = loop.time()
        for mid, fut, call in entries:  # registered before the write: an ack can never beat its future
            pending[mid] = (fut, call, batch, t_send)
        try:
            self._writer.write(data)
        except (OSError, ConnectionError, RuntimeError) as exc:
            for mid in ids:
                pending.pop(mid, None)
            raise _lost(f"write to {self.host}:{self.port} failed: {exc}", unresolved=tuple(ids)) from exc
        self.stats.messages_sent += len(ids)
        if self._observers:
            self._notify_send(ids, calls, batch, t_send)
        return Submission(self, tuple(ids), tuple(calls), batch, tuple(futs))

    def _raise_not_connected(self) -> None:
        if self._state is ClientState.LOST:
            raise _lost(f"connection to {self.host}:{self.port} is lost, nothing was sent "
                        "(call connect() to reconnect)")
        raise ClientStateError(f"not connected (state {self._state.value})")

    async def _ensure_connected(self) -> None:
        if self._state is ClientState.LOST and self.auto_reconnect:
            if self._connect_lock is None:
                self._connect_lock = asyncio.Lock()
            async with self._connect_lock:
                if self._state is ClientState.LOST:
                    log.info("reconnecting to %s:%s (nothing is re-sent)", self.host, self.port)
                    await self.connect()

    # ------------------------------------------------------------------------------------------- waiting
    async def _wait(self, sub: Submission, timeout_s: float | None) -> tuple[MessageResult, ...]:
        futs = sub.futures
        timeout = self.ack_timeout_s if timeout_s is None else timeout_s
        try:
            try:
                async with asyncio.timeout(timeout):
                    # Acks come in order, so waiting for the last one first costs one wake-up per batch.
                    for f in (futs[-1], *futs) if len(futs) > 1 else futs:
                        if not f.done():
                            try:
                                await f
                            except ConnectionLost:
                                pass  # collected below, with the whole batch's acked/unresolved sets
            except TimeoutError:
                missing = tuple(mid for mid, f in zip(sub.ids, futs) if not f.done() or f.cancelled())
                raise AckTimeout(f"no ack within {timeout} s for {len(missing)} of {len(futs)} message(s) "
                                 f"{list(missing)}", pending=missing) from None
            failed = [f.cancelled() or f.exception() is not None for f in futs]
            if any(failed):
                first = next(f.exception() for f, bad in zip(futs, failed) if bad and not f.cancelled())
                raise _lost(getattr(first, "reason", "connection lost"),
                            acked=tuple(mid for mid, bad in zip(sub.ids, failed) if not bad),
                            unresolved=tuple(mid for mid, bad in zip(sub.ids, failed) if bad)) from first
            results = tuple([f.result() for f in futs])
        finally:
            self._release(sub)
        for r in results:
            status = r.ack.status
            if status is not Status.DONE:
                exc: CommandError | CommandAborted = (
                    CommandError(r.ack, r.skill) if status is Status.ERROR else CommandAborted(r.ack, r.skill))
                exc.results = results  # type: ignore[union-attr]
                raise exc
        return results

    def _release(self, sub: Submission) -> None:
        """Remove a submission's messages from the registry (idempotent); remember the unacked ones."""
        if sub._settled:
            return
        sub._settled = True
        pending = self._pending
        abandoned = self._abandoned
        for mid, fut in zip(sub.ids, sub.futures):
            if pending.pop(mid, None) is not None:
                abandoned[mid] = None
                if len(abandoned) > _ABANDONED_MEMORY:
                    del abandoned[next(iter(abandoned))]
            if fut.done():
                if not fut.cancelled():
                    fut.exception()  # mark retrieved
            else:
                fut.cancel()

    # ------------------------------------------------------------------------------------------- public API
    def submit(self, *commands: Command | SkillCall) -> Submission:
        """Write all messages of ``commands`` in one write and return at once with a future per message.

        Low-level: the caller must ``await sub.wait()`` or call ``sub.cancel()``. Raises ClientStateError or
        ConnectionLost when not connected (nothing is written then).
        """
        return self._send(_calls_of(commands))

    async def cmdexec(self, *commands: Command, timeout_s: float | None = None) -> ExecResult:
        """Execute commands one by one: each command's messages are written together, then all their acks are
        awaited before the next command is written (paper: ``RobotClient.cmdexec``).

        ``timeout_s`` limits each command's wait (``None``: ``ack_timeout_s``). Raises CommandError /
        CommandAborted at the first failing command (later commands are not sent), ConnectionLost (``acked`` /
        ``unresolved`` cover this call's messages; commands after the one in flight were never sent), AckTimeout.
        """
        if not commands:
            raise ValueError("commands: at least one command is required")
        per_command = [(c, _calls_of((c,))) for c in commands]
        await self._ensure_connected()
        done: list[CommandResult] = []
        acked: list[str] = []
        for command, calls in per_command:
            sub = self._send(calls)
            try:
                results = await self._wait(sub, timeout_s)
            except ConnectionLost as exc:
                raise _lost(getattr(exc, "reason", "connection lost"), acked=(*acked, *exc.acked),
                            unresolved=exc.unresolved) from exc
            except (CommandError, CommandAborted) as exc:
                exc.completed = tuple(done)  # type: ignore[union-attr]
                raise
            acked.extend(sub.ids)
            done.append(CommandResult(command, results))
        return ExecResult(tuple(done))

    async def cmdexec_joined(self, *commands: Command, timeout_s: float | None = None) -> ExecResult:
        """Write the messages of all commands in ONE write, then await all acks (paper: ``cmdexec_joined``).

        Raises as :meth:`cmdexec`; an error is raised after all acks of the batch are in.
        """
        if not commands:
            raise ValueError("commands: at least one command is required")
        per_command = [(c, _calls_of((c,))) for c in commands]
        await self._ensure_connected()
        sub = self._send([call for _, calls in per_command for call in calls])
        results = await self._wait(sub, timeout_s)
        out = []
        i = 0
        for command, calls in per_command:
            out.append(CommandResult(command, results[i:i + len(calls)]))
            i += len(calls)
        return ExecResult(tuple(out))

    async def stop(self, *, timeout_s: float | None = None) -> MessageResult:
        """Send the ``stop`` skill at once, past whatever is queued (extension; see docs/protocol.md).

        The server aborts the motion in progress, acks every command not yet done ``aborted`` (their waiters
        raise CommandAborted) and then acks the stop ``done``; this returns the stop's result (pose at rest).
        Raises CommandError if the server does not know ``stop`` (an original V+ AdeptServer halts instead).
        """
        return (await self._wait(self._send((SkillCall(STOP_SKILL),)), timeout_s))[0]

    async def here(self, *, timeout_s: float | None = None) -> Pose:
        """The robot's current pose (``here`` extension skill)."""
        return (await self._wait(self._send((SkillCall(HERE_SKILL),)), timeout_s))[0].ack.pose

    async def hello(self, *, timeout_s: float | None = None) -> tuple[int | None, str]:
        """``(protocol_version, server_name)`` from the ``hello`` extension skill."""
        ack = (await self._wait(self._send((SkillCall(HELLO_SKILL),)), timeout_s))[0].ack
        version: int | None
        try:
            version = int(ack.extra[0])
        except (IndexError, ValueError):
            version = None
        return version, (ack.extra[1] if len(ack.extra) > 1 else "")

    # ------------------------------------------------------------------------------------------- observers
    def _notify_send(self, ids: list[str], calls: Sequence[SkillCall], batch: int, t_send: float) -> None:
        for mid, call in zip(ids, calls):
            msg = SentMessage(mid, call.skill, call.args, batch, t_send)
            for obs in self._observers:
                try:
                    obs.on_send(msg)
                except Exception:
                    log.exception("observer %r failed in on_send", obs)

    def _notify_ack(self, result: MessageResult) -> None:
        for obs in self._observers:
            try:
                obs.on_ack(result)
            except Exception:
                log.exception("observer %r failed in on_ack", obs)

    def __repr__(self) -> str:
        return f"<RobotClient {self.host}:{self.port} {self._state.value} pending={len(self._pending)}>"


def _lost(reason: str, *, acked: tuple[str, ...] = (), unresolved: tuple[str, ...] = ()) -> ConnectionLost:
    exc = ConnectionLost(reason, acked=acked, unresolved=unresolved)
    exc.reason = reason  # type: ignore[attr-defined]  # the text without the id lists, to re-raise merged
    return exc


def _calls_of(commands: Iterable[Command | SkillCall]) -> tuple[SkillCall, ...]:
    out: list[SkillCall] = []
    for i, c in enumerate(commands):
        if isinstance(c, Command):
            out.extend(c.calls())
        elif isinstance(c, SkillCall):
            out.append(c)
        else:
            raise TypeError(f"commands[{i}]: {c!r} is not a Command")
    if not out:
        raise ValueError("commands: nothing to send")
    return out  # type: ignore[return-value]
