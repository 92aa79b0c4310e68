"""RobotClient: the asyncio side of the robot line protocol (the paper's MasterControlNode ↔ RobotServer link).

It sits between the commands (:mod:`aioadept.commands`, values that expand to skill calls) and the TCP connection,
and drives the sans-IO core (:mod:`aioadept.protocol`) over asyncio::

    async with RobotClient("127.0.0.1", 1234) as robot:
        await robot.cmdexec(MoveJoints([0, -90, 180, 0, 90, 0]))          # one command at a time
        res = await robot.cmdexec_joined(SetSpeed(20), MoveToolZ(2.5))     # all messages in one write
        print(res.pose, res.messages[-1].t_recv_s - res.messages[0].t_send_s)

How it works, and the promises it keeps:

- One write path (:meth:`RobotClient._send`): IDs are allocated, every message of the batch is registered in the
  pending registry (ID -> submission) *before* the bytes are written, then the batch goes out in one write.
- One place routes acks (:meth:`RobotClient._feed`): on TCP it runs in the transport's ``data_received`` (a
  protocol, not a reader task: one loop turn less per round trip); with a ``connector`` that returns asyncio
  streams (tests, in-memory pairs) a single reader task feeds it. It does nothing else: no per-message logging, no
  per-message task. A waiter waits on one future per batch; ``submit`` adds a future per message.
- Every wait has a timeout. The default timeouts share one watchdog timer (their deadlines come in order); a
  per-call ``timeout_s`` gets its own timer.
- Every waiter removes its messages from the registry in ``finally``; an ack that arrives later for a cancelled or
  timed-out message is dropped quietly and counted (:attr:`ClientStats.late_acks`).
- No command is ever re-sent. When the connection drops, every pending wait fails with :class:`ConnectionLost`,
  whose ``acked`` / ``unresolved`` say what is known done and what may or may not have run on the robot.
  Reconnecting is an explicit :meth:`connect` (or the opt-in ``auto_reconnect=True``, which reconnects before the
  *next* new call, ``stop``/``here``/``hello`` included, and still re-sends nothing).
- The stop path (:meth:`RobotClient.stop`): written at once (no client-side write queue exists: every call writes
  in the loop turn it is ready), in a task of the client so cancelling the caller cannot cancel it, sent once more
  on a new connection if the connection is lost before its ack (a repeated stop cannot move the robot); a call
  that began before a stop and had not yet written its command never writes it (:class:`AbortedBeforeSend`).
- Values are checked before anything is sent: timeouts (finite, > 0), ``id_start``, the commands themselves
  (:mod:`aioadept.commands`). IDs never repeat one still pending or given up, and never are ``00000000``.
- Observers (``on_send`` / ``on_ack``, see docs/interfaces.md) get loop-clock timestamps taken at write and read.
"""

from __future__ import annotations

import asyncio
import enum
import functools
import logging
import math
import numbers
import operator
import secrets
import socket
import time
from collections import deque
from itertools import chain
from collections.abc import Awaitable, Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from aioadept.commands import Command
from aioadept.errors import (
    AbortedBeforeSend,
    AckTimeout,
    ClientStateError,
    CommandAborted,
    CommandError,
    ConnectError,
    ConnectionLost,
    NotARobotServer,
    RemoteProtocolError,
)
from aioadept.geometry import Pose
from aioadept.protocol.messages import _make_ack, fast_constructor
from aioadept.protocol import (
    HELLO_SKILL,
    HERE_SKILL,
    MAX_ACK_LINE,
    NO_ID,
    STOP_SKILL,
    Ack,
    AckParser,
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
_CLOSE_FLUSH_S = 1.0
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
        return self.ack.status is _DONE

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
    """What :meth:`RobotClient.cmdexec` / :meth:`RobotClient.cmdexec_joined` return.

    ``messages``: every message's result in send order; ``commands``: the same grouped per command (built on
    first use, since most callers only look at the last pose).
    """

    messages: tuple[MessageResult, ...]
    sent: tuple[Command | None, ...]
    """The commands, in order."""
    sizes: tuple[int, ...] = field(repr=False)
    """How many messages each command has."""

    @property
    def commands(self) -> tuple[CommandResult, ...]:
        out = []
        i = 0
        for command, n in zip(self.sent, self.sizes):
            out.append(CommandResult(command, self.messages[i:i + n]))
            i += n
        return tuple(out)

    @property
    def pose(self) -> Pose:
        """The pose in the last ack."""
        return self.messages[-1].ack.pose

    def __iter__(self) -> Iterator[MessageResult]:
        return iter(self.messages)

    def __len__(self) -> int:
        return len(self.messages)

    def __getitem__(self, index: int) -> MessageResult:
        return self.messages[index]


class ClientState(str, enum.Enum):
    NEW = "new"
    CONNECTED = "connected"
    LOST = "lost"          # the peer closed or the socket failed; connect() again to go on
    CLOSED = "closed"      # close() was called; connect() again to reuse


_DONE = Status.DONE
_BASE_TIME = asyncio.BaseEventLoop.time
_BASE_CREATE_FUTURE = asyncio.BaseEventLoop.create_future
# Enum member lookups cost ~0.3 us each in 3.11; the hot paths compare against these module constants instead.
_NEW, _CONNECTED, _LOST, _CLOSED = ClientState.NEW, ClientState.CONNECTED, ClientState.LOST, ClientState.CLOSED


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
_W_ACKED = 0       # waiter results: why a batch's waiter woke up
_W_TIMED_OUT = 1
_W_LOST = 2


class Submission:
    """The messages written together in one write (one batch), and their state in the pending registry.

    Returned by :meth:`RobotClient.submit`. ``futures`` holds a future per message (only for ``submit``; the
    ``cmdexec`` path does without them): each resolves to a :class:`MessageResult` whatever the ack's status (so
    an ignored future never logs "exception never retrieved"), or fails with :class:`ConnectionLost`. :meth:`wait`
    turns statuses into errors and removes the messages from the registry; call it (or :meth:`cancel`) once.
    """

    # No __slots__: the rarely changed fields are class-level defaults, so creating one (per write, on the round
    # trip's critical path) sets only what every batch needs.
    futures: tuple[asyncio.Future[MessageResult], ...] | None = None
    _waiter: asyncio.Future[int] | None = None
    _deadline = 0.0
    _timer: asyncio.TimerHandle | None = None
    _settled = False
    _lost_reason: str | None = None
    _first_bad = -1  # index of the first non-done ack (in send order), -1 if none
    _next_i = 0  # where the next ack is expected in ``ids`` (one after the previous ack's)

    def __init__(self, client: RobotClient, ids: tuple[str, ...], calls: Sequence[SkillCall], batch: int) -> None:
        self._client = client
        self.ids = ids
        self.calls = calls
        self.batch = batch
        self.t_send_s = 0.0
        self.results: list[MessageResult | None] = [None] * len(ids)
        self.remaining = len(ids)

    def _index(self, mid: str) -> int:
        """The index of message ``mid`` (registered, so present); expected one after the previous ack's."""
        ids = self.ids
        i = self._next_i
        if i >= len(ids) or ids[i] != mid:
            i = ids.index(mid)
        self._next_i = i + 1
        return i

    def done(self) -> bool:
        """True when every message is acked or the connection was lost."""
        return self.remaining == 0 or self._lost_reason is not None

    async def wait(self, *, timeout_s: float | None = None) -> tuple[MessageResult, ...]:
        """All results in send order. Raises CommandError / CommandAborted (first failing message, after all
        acks are in; ``exc.results`` holds them), ConnectionLost, or AckTimeout (``timeout_s=None``: the client's
        ``ack_timeout_s``; else finite and > 0, or ValueError)."""
        if timeout_s is not None:
            _check_timeout("timeout_s", timeout_s)
        return await self._client._wait(self, timeout_s)

    def cancel(self) -> None:
        """Stop waiting: forget the messages (late acks are dropped and counted). The robot is not stopped."""
        self._client._release(self)

    def __repr__(self) -> str:
        done = len(self.ids) - self.remaining
        return f"<Submission batch={self.batch} ids={list(self.ids)} acked={done}/{len(self.ids)}>"


# ---------------------------------------------------------------------------------------------------- client
class RobotClient:
    """An asyncio client of a RobotServer (the V+ AdeptServer, or ``aioadept sim``).

    Reusable (``connect`` again after ``close`` or a lost connection), not reentrant. Options:

    - ``connect_timeout_s``: limit of :meth:`connect` (→ :class:`ConnectError`).
    - ``ack_timeout_s``: default limit of every wait for acks (→ :class:`AckTimeout`); ``None`` waits forever.
      A break waits for the whole motion, so keep this above your longest motion.
    - ``observers``: objects with ``on_send(SentMessage)`` / ``on_ack(MessageResult)``.
    - ``id_start``: first message ID as an int in 1..0xFFFFFFFF (IDs count up from a random start by default,
      skip the reserved ``00000000`` and any ID still pending or given up on this client).
    - ``auto_reconnect``: after a lost connection, reconnect before the next new call (commands, ``stop``,
      ``here``, ``hello``). Never re-sends a command; only a stop whose connection was lost before its ack is sent
      again (see :meth:`stop`).

    Every timeout, here and in each method's ``timeout_s``, must be a finite number of seconds > 0 (``None``
    where documented); anything else raises ``ValueError`` at once, before anything is sent.
    - ``connector``: an async callable returning ``(reader, writer)``, to run over other streams (e.g.
      :func:`aioadept.testing.memory_connector`); ``host``/``port`` are then only used in messages.
    - ``hello_timeout_s``: after each connect, send ``hello`` and wait this long for its ack; a peer that sends
      nothing parseable back in time (a ZeroMQ port, a silent server) or closes the connection is not a
      RobotServer: :meth:`connect` closes it and raises :class:`NotARobotServer`. An ``error`` ack (the
      ``-406`` "unknown skill" of a server without the extensions) proves a RobotServer and connect goes on.
      ``None`` (the default): no check. Keep it ``None`` for the original V+ AdeptServer, whose task halts on
      any unknown skill (docs/protocol.md section 6). The answer is in :attr:`server_hello`; the exchange is
      not shown to observers.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 1234, *, connect_timeout_s: float = 5.0,
                 ack_timeout_s: float | None = 60.0, observers: Iterable[Observer] = (),
                 id_start: int | None = None, auto_reconnect: bool = False,
                 connector: Connector | None = None, max_line: int = MAX_ACK_LINE,
                 hello_timeout_s: float | None = None) -> None:
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 0xFFFF:
            raise ValueError(f"port: {port!r} is not a TCP port number (0..65535)")
        if id_start is not None and (isinstance(id_start, bool) or not isinstance(id_start, int)
                                     or not 0 < id_start <= 0xFFFFFFFF):
            raise ValueError(f"id_start: {id_start!r} is not an int in 1..0xFFFFFFFF (00000000 is reserved)")
        self.host = host
        self.port = port
        self.connect_timeout_s = connect_timeout_s  # validated by the properties
        self.ack_timeout_s = ack_timeout_s
        self.auto_reconnect = auto_reconnect
        self.hello_timeout_s = _check_timeout("hello_timeout_s", hello_timeout_s)
        self.server_hello: tuple[int | None, str] | None = None
        """``(protocol_version, server_name)`` from the connect-time ``hello`` check; ``None`` without the check
        or from a server that answered it with an error ack (no extensions)."""
        self._connector = connector
        self._observers: list[Observer] = list(observers)
        self._ids = IdAllocator(secrets.randbits(32) if id_start is None else id_start)
        self._framer = LineFramer(max_line=max_line)
        self._parser = AckParser()
        # id -> submission. The one registry of pending messages. An ack's index in its submission is found from
        # the one after the previous ack (acks come in order), else by search (Submission._index).
        self._pending: dict[str, Submission] = {}
        # Waiters with the default timeout, in deadline order, watched by ONE timer (a timer per wait costs
        # ~10-30 us of loop time per round trip on a small VM; deadlines of a constant timeout come in order).
        self._deadlines: deque[Submission] = deque()
        self._watchdog: asyncio.TimerHandle | None = None
        # IDs given up by their waiter (cancel/timeout), to count their late acks; dict as an ordered set.
        self._abandoned: dict[str, None] = {}
        self._batch = 0
        self._issued = 0  # IDs taken from self._ids so far (see _send)
        self._state = _NEW
        self._transport: asyncio.BaseTransport | None = None
        self._write: Callable[[bytes], None] | None = None
        self._transport_closed: asyncio.Future[None] | None = None
        self._reader_task: asyncio.Task[None] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._loop_fns: tuple = (None, None, None)  # see _bind_loop
        self._lost_reason: BaseException | None = None
        self._server_error: Ack | None = None  # the last error ack without an ID on this connection
        self._in_context = False
        self._connect_lock: asyncio.Lock | None = None
        self._closes = 0  # close() calls, so a reconnect that raced one does not resurrect the client
        # stop() calls so far: a call that began before a stop and had not yet written its command never writes it
        self._stops = 0
        self._stop_tasks: set[asyncio.Task[MessageResult]] = set()
        self.stats = ClientStats()

    @property
    def connect_timeout_s(self) -> float:
        """Limit of :meth:`connect` and of each reconnect (seconds, finite, > 0)."""
        return self._connect_timeout_s

    @connect_timeout_s.setter
    def connect_timeout_s(self, value: float) -> None:
        self._connect_timeout_s = _check_timeout("connect_timeout_s", value, none_ok=False)

    @property
    def ack_timeout_s(self) -> float | None:
        """Default limit of every wait for acks (seconds, finite, > 0; ``None``: wait forever)."""
        return self._ack_timeout_s

    @ack_timeout_s.setter
    def ack_timeout_s(self, value: float | None) -> None:
        self._ack_timeout_s = _check_timeout("ack_timeout_s", value)

    # ------------------------------------------------------------------------------------------- lifecycle
    @property
    def state(self) -> ClientState:
        return self._state

    @property
    def connected(self) -> bool:
        return self._state is _CONNECTED

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
        """Open the connection and start reading. Raises ConnectError, or ClientStateError if connected."""
        if self._state is _CONNECTED:
            raise ClientStateError(f"already connected to {self.host}:{self.port}")
        await self._teardown()  # a lost connection's reader task and transport, if any
        loop = asyncio.get_running_loop()
        reader: asyncio.StreamReader | None = None
        try:
            async with asyncio.timeout(self._connect_timeout_s):
                if self._connector is not None:
                    reader, writer = await self._connector()
                    transport: asyncio.BaseTransport = writer.transport
                    write = writer.write
                    closed = None
                else:
                    proto = _AckProtocol(self, loop)
                    transport, _ = await loop.create_connection(lambda: proto, self.host, self.port)
                    write = transport.write  # type: ignore[attr-defined]
                    closed = proto.closed
        except TimeoutError:
            raise ConnectError(f"connect to {self.host}:{self.port}: no answer in {self.connect_timeout_s} s") \
                from None
        except OSError as exc:
            raise ConnectError(f"connect to {self.host}:{self.port}: {exc}") from exc
        sock = transport.get_extra_info("socket")
        if sock is not None:
            try:  # small writes must leave at once (asyncio sets this too; uvloop may not)
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            except (OSError, AttributeError):
                pass
        self._loop = loop
        self._transport, self._write, self._transport_closed = transport, write, closed
        self._framer.reset()
        self._lost_reason = None
        self._server_error = None
        self._state = _CONNECTED
        if reader is not None:
            self._reader_task = loop.create_task(self._read_loop(reader), name=f"RobotClient reader {self.host}")
        if self.hello_timeout_s is not None:
            await self._check_hello(self.hello_timeout_s)

    async def _check_hello(self, timeout_s: float) -> None:
        """The connect-time ``hello`` exchange (``hello_timeout_s``): is the peer a RobotServer at all?"""
        # Observers see the user's traffic only (a run's timing tables must not start with our probe); connect()
        # is awaited before any command of this client is sent, so nothing else is written meanwhile.
        observers, self._observers = self._observers, []
        try:
            self.server_hello = await self.hello(timeout_s=timeout_s)
        except CommandError as exc:  # it speaks the protocol, without the hello extension: go on
            self.server_hello = None
            log.info("robot server %s:%s answered hello with an error (code %s): a server without the "
                     "extensions, going on", self.host, self.port, exc.code)
        except (AckTimeout, ConnectionLost) as exc:
            await self.close()
            self._state = _NEW  # connect() may be called again
            said = " (it closed the connection)" if isinstance(exc, ConnectionLost) else ""
            raise NotARobotServer(f"{self.host}:{self.port} answered nothing like a RobotServer within "
                                  f"{timeout_s:g} s{said}: is this the robot's port?") from None
        finally:
            self._observers = observers

    async def close(self) -> None:
        """Close the connection; pending waits fail with ConnectionLost. Idempotent."""
        was = self._state
        self._state = _CLOSED
        self._closes += 1
        if was is _CONNECTED:
            self._fail_pending("client closed the connection")
        await self._teardown()

    async def _teardown(self) -> None:
        task, transport, closed = self._reader_task, self._transport, self._transport_closed
        self._reader_task = None
        self._transport = None
        self._transport_closed = None
        self._write = None
        if self._watchdog is not None:
            self._watchdog.cancel()
            self._watchdog = None
        self._deadlines.clear()
        if task is not None and not task.done():
            task.cancel()
        if transport is not None:
            transport.close()
        if task is not None:
            try:
                await task
            except asyncio.CancelledError:
                # Our own cancel of the reader; but if *we* are being cancelled, let that through.
                current = asyncio.current_task()
                if current is not None and current.cancelling():
                    raise
        if closed is not None:
            try:  # close() waits to flush what we wrote; a peer that never reads must not hang us
                async with asyncio.timeout(_CLOSE_FLUSH_S):
                    await asyncio.shield(closed)
            except TimeoutError:
                assert transport is not None
                transport.abort()  # type: ignore[attr-defined]
                await closed

    # ------------------------------------------------------------------------------------------- reading
    async def _read_loop(self, reader: asyncio.StreamReader) -> None:
        """The only reader: cut the stream into lines and route each ack to its submission."""
        feed = self._feed
        loop_time = self._bind_loop(asyncio.get_running_loop())[1]
        reason: BaseException | None = None
        try:
            while True:
                data = await reader.read(_READ_SIZE)
                if not data:
                    break
                feed(data, loop_time())
        except (OSError, ConnectionError) as exc:
            reason = exc
        except Exception as exc:  # a bug here must not leave waiters hanging forever
            log.exception("RobotClient reader failed")
            reason = exc
        # CancelledError (close/teardown) propagates: close() fails pending waiters itself.
        self._on_lost(reason)

    def _feed(self, data: bytes, t_recv: float) -> None:
        """Route every ack in ``data`` (read at loop time ``t_recv``). The hot path of the client."""
        pending_pop = self._pending.pop
        parser = self._parser
        pose_text, pose = parser._pose_text, parser._pose
        times_text = parser._times_text
        t_start, t_done = parser._times
        make_result = _make_result
        make_ack = _make_ack
        ack_twin = _ACK_TWIN
        result_twin = _RESULT_TWIN
        ack_cls = Ack
        result_cls = MessageResult
        isfinite = math.isfinite
        notify = self._notify_ack if self._observers else None
        cur = None  # the submission of the previous ack, and its fields: consecutive acks mostly share one
        calls: Sequence[SkillCall] = ()
        results: list[MessageResult | None] = []
        futs = None
        ids: tuple[str, ...] = ()
        batch = 0
        j = 0
        t_send = 0.0
        fast = 0  # acks routed here (not by _route)
        count = 0  # of them, acks of `cur` not yet subtracted from cur.remaining (one update per run of a batch)
        try:
            for item in self._framer.feed(data):
                if type(item) is not bytes:
                    self._unexpected("oversize", item.head, t_recv)  # type: ignore[union-attr]
                    continue
                # Fast path, inline because it runs once per ack: a plain `done` ack carrying the same pose text as
                # the previous ack, checked exactly as AckParser.parse checks it (times text repeated within a
                # millisecond is not parsed again either). Anything else takes _route().
                parts = item.split(b":")  # type: ignore[union-attr]
                if len(parts) == 4 and parts[3] == pose_text and parts[1] == b"done":
                    # No ID syntax check needed: only IDs we issued are in the registry, so a hit proves it valid;
                    # UnicodeDecodeError and a wrong number of times are ValueErrors like a bad float.
                    try:
                        mid = parts[0].decode("ascii")
                        if parts[2] != times_text:
                            ts, td = map(float, parts[2].split(b","))
                            if not isfinite(ts + td):
                                raise ValueError
                            times_text, t_start, t_done = parts[2], ts, td
                    except ValueError:
                        mid = ""
                    sub = pending_pop(mid, None) if mid else None
                    if sub is not None:
                        if sub is not cur:
                            if count:
                                _settle(cur, count)  # type: ignore[arg-type]
                                fast += count
                                count = 0
                            if cur is not None:
                                cur._next_i = j
                            cur = sub
                            calls, results, futs, ids = sub.calls, sub.results, sub.futures, sub.ids
                            batch, t_send, j = sub.batch, sub.t_send_s, sub._next_i
                        # Its index: one after the previous ack's (acks come in order), else search.
                        i = j if j < len(ids) and ids[j] == mid else ids.index(mid)
                        j = i + 1
                        call = calls[i]
                        if result_twin is not None:
                            # make_result(..., make_ack(...)) inline: two calls cost more than the objects
                            ack = ack_twin()
                            ack.id = mid
                            ack.status = _DONE
                            ack.t_start_s = t_start
                            ack.t_done_s = t_done
                            ack.pose = pose
                            ack.extra = ()
                            ack.__class__ = ack_cls
                            result = result_twin()
                            result.id = mid
                            result.skill = call.skill
                            result.args = call.args
                            result.batch = batch
                            result.t_send_s = t_send
                            result.t_recv_s = t_recv
                            result.ack = ack
                            result.__class__ = result_cls
                        else:
                            result = make_result(mid, call.skill, call.args, batch, t_send, t_recv,
                                                 make_ack(mid, _DONE, t_start, t_done, pose, ()))
                        results[i] = result
                        count += 1
                        if futs is not None and not futs[i].done():
                            futs[i].set_result(result)
                        if notify is not None:
                            notify(result)
                        continue
                self._route(item, t_recv)  # type: ignore[arg-type]
                pose_text, pose = parser._pose_text, parser._pose
                times_text = parser._times_text
                t_start, t_done = parser._times
        finally:
            if cur is not None:
                cur._next_i = j
            fast += count
            if count:  # _settle(cur, count) inline
                cur.remaining -= count  # type: ignore[union-attr]
                if not cur.remaining and cur._waiter is not None and not cur._waiter.done():  # type: ignore
                    cur._waiter.set_result(_W_ACKED)  # type: ignore[union-attr]
            self.stats.acks += fast
            if times_text is not parser._times_text:  # keep the last times for the next read
                parser._times_text, parser._times = times_text, (t_start, t_done)

    def _route(self, line: bytes, t_recv: float) -> None:
        """The general path for one ack line: any status, any pose, unknown IDs, garbage."""
        try:
            ack = self._parser.parse(line)
        except RemoteProtocolError:
            self._unexpected("bad_line", line, t_recv)
            return
        sub = self._pending.pop(ack.id, None)
        if sub is None:
            self._unmatched(ack, line, t_recv)
            return
        i = sub._index(ack.id)
        call = sub.calls[i]
        result = _make_result(ack.id, call.skill, call.args, sub.batch, sub.t_send_s, t_recv, ack)
        sub.results[i] = result
        if ack.status is not _DONE and (sub._first_bad < 0 or i < sub._first_bad):
            sub._first_bad = i
        if sub.futures is not None and not sub.futures[i].done():
            sub.futures[i].set_result(result)
        sub.remaining -= 1
        if not sub.remaining and sub._waiter is not None and not sub._waiter.done():
            sub._waiter.set_result(_W_ACKED)
        self.stats.acks += 1
        if self._observers:
            self._notify_ack(result)

    def _unmatched(self, ack: Ack, line: bytes, t_recv: float) -> None:
        if ack.id in self._abandoned:
            del self._abandoned[ack.id]
            self.stats.late_acks += 1
        elif ack.id == NO_ID:
            # Kept for the loss that usually follows: a server refusing us (too many clients, address not
            # allowed) sends one such ack and closes, and the user should read why, not just "closed by peer".
            self._server_error = ack
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
        if self._state is not _CONNECTED:
            return
        self._state = _LOST
        self._lost_reason = reason
        why = f"connection to {self.host}:{self.port} lost" + (f": {reason}" if reason else " (closed by peer)")
        if self._server_error is not None:
            err = self._server_error
            why += f" after the server's error ack: {err.error_message} (code {err.error_code})"
        log.warning("%s with %d message(s) unacked", why, len(self._pending))
        self._fail_pending(why)

    def _fail_pending(self, why: str) -> None:
        pending, self._pending = self._pending, {}
        subs = {id(sub): sub for sub in pending.values()}  # in send order
        for sub in subs.values():
            if sub.futures is not None:
                for mid, fut in zip(sub.ids, sub.futures):
                    if mid in pending and not fut.done():
                        # Per message; wait() merges them into one error with the whole batch's sets.
                        fut.set_exception(_lost(why, unresolved=(mid,)))
        for sub in subs.values():
            sub._lost_reason = why
            if sub._waiter is not None and not sub._waiter.done():
                sub._waiter.set_result(_W_LOST)

    # ------------------------------------------------------------------------------------------- writing
    def _send(self, calls: Sequence[SkillCall], *, futures: bool = False) -> Submission:
        """The one write path: allocate IDs, register the messages, then write the batch in one call."""
        if self._state is not _CONNECTED:
            self._raise_not_connected()
        loop = self._loop
        write = self._write
        assert loop is not None and write is not None
        fns = self._loop_fns
        if fns[0] is not loop:
            fns = self._bind_loop(loop)
        n = len(calls)
        pending = self._pending
        # An ID is never one still pending or given up (its late ack may still come) on this client. The counter
        # cycles through the 2**32 - 1 IDs other than 00000000, so the first 2**32 - 1 IDs it issues are all
        # distinct: only after that (_issued counts them) can an ID repeat, and only then are IDs checked (the
        # check on every send costs ~0.1-0.25 us per message).
        issued = self._issued = self._issued + n
        if n == 1:
            # IdAllocator.next() inline (a round trip's send; a call costs more than the work): the next ID unless
            # it is 00000000 or the last before the wrap, which next() handles.
            allocator = self._ids
            k = allocator._next
            if 0 < k < 0xFFFFFFFF:
                allocator._next = k + 1
                mid = "%08x" % k
            else:
                mid = allocator.next()
            if issued > 0xFFFFFFFF and (mid in pending or mid in self._abandoned):
                mid = self._unused_ids(1)[0]
            ids: tuple[str, ...] = (mid,)
            data = f"{mid}:{calls[0].wire}\r\n".encode("ascii")
        else:
            ids = tuple(self._ids.take(n))
            if issued > 0xFFFFFFFF and (not pending.keys().isdisjoint(ids)
                                        or not self._abandoned.keys().isdisjoint(ids)):
                ids = self._unused_ids(n)
            data = "".join([f"{mid}:{call.wire}\r\n" for mid, call in zip(ids, calls)]).encode("ascii")
        batch = self._batch = self._batch + 1
        # Submission(self, ids, calls, batch), inline for the same reason.
        sub = _new_submission(Submission)
        sub._client = self
        sub.ids = ids
        sub.calls = calls
        sub.batch = batch
        sub.results = [None] * n
        sub.remaining = n
        if futures:
            new_future = fns[2]
            sub.futures = tuple(new_future() for _ in range(n))
        # Registered before the write, so an ack can never beat its entry.
        if n == 1:
            pending[ids[0]] = sub
        else:
            pending.update(dict.fromkeys(ids, sub))
        sub.t_send_s = fns[1]()
        try:
            write(data)
        except (OSError, ConnectionError, RuntimeError) as exc:
            for mid in ids:
                pending.pop(mid, None)
            sub._settled = True
            raise _lost(f"write to {self.host}:{self.port} failed: {exc}", unresolved=tuple(ids)) from exc
        self.stats.messages_sent += n
        if self._observers:
            self._notify_send(sub)
        return sub

    def _unused_ids(self, n: int) -> tuple[str, ...]:
        """The next ``n`` IDs that are neither pending nor given up (the slow path of :meth:`_send`)."""
        out: dict[str, None] = {}
        pending, abandoned, allocator = self._pending, self._abandoned, self._ids
        while len(out) < n:
            mid = allocator.next()
            self._issued += 1
            if mid not in pending and mid not in abandoned:
                out[mid] = None
        return tuple(out)

    def _bind_loop(self, loop: asyncio.AbstractEventLoop) -> tuple:
        """``(loop, clock, new_future)``: ``loop.time`` and ``loop.create_future`` without a Python frame each when
        they are asyncio's own (``time.monotonic()`` and ``Future(loop=loop)``, exactly what those do)."""
        clock = loop.time
        if getattr(clock, "__func__", None) is _BASE_TIME:
            clock = time.monotonic
        new_future: Callable[[], asyncio.Future] = loop.create_future
        if getattr(new_future, "__func__", None) is _BASE_CREATE_FUTURE:
            new_future = functools.partial(asyncio.Future, loop=loop)
        fns = self._loop_fns = (loop, clock, new_future)
        return fns

    def _raise_not_connected(self) -> None:
        if self._state is _LOST:
            said = ""
            if self._server_error is not None:
                err = self._server_error
                said = f" after the server's error ack: {err.error_message} (code {err.error_code})"
            raise _lost(f"connection to {self.host}:{self.port} is lost{said}, nothing was sent "
                        "(call connect() to reconnect)")
        raise ClientStateError(f"not connected (state {self._state.value})")

    async def _ensure_connected(self) -> None:
        """Reconnect a lost connection if ``auto_reconnect`` (ConnectError if that fails); otherwise leave the
        state to :meth:`_send`, which raises ConnectionLost / ClientStateError."""
        if self._state is _LOST and self.auto_reconnect:
            if self._connect_lock is None:
                self._connect_lock = asyncio.Lock()
            closes = self._closes
            async with self._connect_lock:
                if self._state is _LOST and self._closes == closes:
                    log.info("reconnecting to %s:%s (nothing is re-sent)", self.host, self.port)
                    await self.connect()
                    if self._closes != closes:  # close() ran while we connected: it wins
                        await self.close()
            if self._closes != closes:
                raise ClientStateError(f"client closed while reconnecting to {self.host}:{self.port}")

    # ------------------------------------------------------------------------------------------- waiting
    async def _wait(self, sub: Submission, timeout_s: float | None,
                    just_sent: bool = False) -> tuple[MessageResult, ...]:
        """``just_sent``: called in the same loop turn as the write, so the deadline counts from the write time
        (the same instant, without reading the clock again)."""
        if sub._settled:
            raise ClientStateError("this submission was already awaited or cancelled")
        try:
            if sub.remaining and sub._lost_reason is None:
                loop = self._loop
                assert loop is not None
                fns = self._loop_fns
                if fns[0] is not loop:
                    fns = self._bind_loop(loop)
                waiter = sub._waiter = fns[2]()
                now = sub.t_send_s if just_sent else fns[1]()
                dq = self._deadlines
                default_s = self._ack_timeout_s
                if timeout_s is None and default_s is not None and (
                        not dq or dq[-1]._deadline <= now + default_s):
                    # _arm's common case inline: joins the watchdog's queue
                    sub._deadline = now + default_s
                    while dq and dq[0]._settled:
                        dq.popleft()
                    dq.append(sub)
                    if self._watchdog is None:
                        self._watchdog = loop.call_at(dq[0]._deadline, self._on_watchdog)
                else:
                    self._arm(sub, default_s if timeout_s is None else timeout_s, timeout_s is None, now)
                why = await waiter
                if why == _W_TIMED_OUT:
                    missing = tuple(mid for mid, r in zip(sub.ids, sub.results) if r is None)
                    raise AckTimeout(f"no ack within {default_s if timeout_s is None else timeout_s} s "
                                     f"for {len(missing)} of {len(sub.ids)} message(s) {list(missing)}",
                                     pending=missing)
            if sub._lost_reason is not None and sub.remaining:
                raise _lost(sub._lost_reason,
                            acked=tuple(mid for mid, r in zip(sub.ids, sub.results) if r is not None),
                            unresolved=tuple(mid for mid, r in zip(sub.ids, sub.results) if r is None))
        finally:
            if sub.remaining or sub._timer is not None or sub.futures is not None:
                self._release(sub)
            else:  # all acked, nothing to cancel or forget: what _release would do
                sub._settled = True
        results: tuple[MessageResult, ...] = tuple(sub.results)  # type: ignore[arg-type]
        if sub._first_bad >= 0:
            r = results[sub._first_bad]
            exc: CommandError | CommandAborted = (
                CommandError(r.ack, r.skill) if r.ack.status is Status.ERROR else CommandAborted(r.ack, r.skill))
            exc.results = results  # type: ignore[union-attr]
            raise exc
        return results

    def _arm(self, sub: Submission, timeout: float | None, default: bool, now: float) -> None:
        if timeout is None:
            return
        loop = self._loop
        assert loop is not None
        deadline = sub._deadline = now + timeout
        dq = self._deadlines
        while dq and dq[0]._settled:  # finished waits leave from the front (batches finish roughly in order)
            dq.popleft()
        if default and (not dq or dq[-1]._deadline <= deadline):
            dq.append(sub)
            if self._watchdog is None:
                self._watchdog = loop.call_at(dq[0]._deadline, self._on_watchdog)
        else:  # a custom timeout, or the default changed: a timer of its own
            sub._timer = loop.call_at(deadline, self._time_out, sub)

    def _on_watchdog(self) -> None:
        self._watchdog = None
        loop = self._loop
        assert loop is not None
        now = loop.time() + 0.001  # the loop may run a timer up to its clock resolution early
        dq = self._deadlines
        while dq:
            sub = dq[0]
            if not sub._settled and sub._deadline > now:
                break
            dq.popleft()
            if not sub._settled:
                self._time_out(sub)
        if dq:
            self._watchdog = loop.call_at(dq[0]._deadline, self._on_watchdog)

    @staticmethod
    def _time_out(sub: Submission) -> None:
        waiter = sub._waiter
        if waiter is not None and not waiter.done():
            waiter.set_result(_W_TIMED_OUT)

    def _release(self, sub: Submission) -> None:
        """Remove a submission's messages from the registry (idempotent); remember the unacked ones."""
        if sub._settled:
            return
        sub._settled = True
        if sub._timer is not None:
            sub._timer.cancel()
        if sub.remaining and sub._lost_reason is None:
            pending = self._pending
            abandoned = self._abandoned
            for mid, r in zip(sub.ids, sub.results):
                if r is None and pending.pop(mid, None) is not None:
                    abandoned[mid] = None
                    if len(abandoned) > _ABANDONED_MEMORY:
                        del abandoned[next(iter(abandoned))]
        if sub.futures is not None:
            for fut in sub.futures:
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
        return self._send(_calls_of(commands), futures=True)

    async def cmdexec(self, *commands: Command, timeout_s: float | None = None) -> ExecResult:
        """Execute commands one by one: each command's messages are written together, then all their acks are
        awaited before the next command is written (paper: ``RobotClient.cmdexec``).

        ``timeout_s`` limits each command's wait (``None``: ``ack_timeout_s``; else finite and > 0, or ValueError
        before anything is sent). Raises CommandError / CommandAborted at the first failing command (later
        commands are not sent; ``exc.completed`` holds the results of those before), ConnectionLost (``acked`` /
        ``unresolved`` cover this call's messages; commands after the one in flight were never sent), AckTimeout,
        ConnectError (an auto-reconnect failed), AbortedBeforeSend (a :meth:`stop` was called after this call
        began and before the command was written: it is never written).
        """
        if timeout_s is not None:
            _check_timeout("timeout_s", timeout_s)
        if len(commands) == 1:  # one command: no merging of per-command results needed
            try:
                calls = commands[0]._calls  # the common case, without per-command calls
            except AttributeError:
                calls = _calls_of(commands)
            if self._state is not _CONNECTED:
                stops = self._stops
                await self._ensure_connected()
                if self._stops != stops:
                    raise AbortedBeforeSend(calls[0].skill)
            try:
                results = await self._wait(self._send(calls), timeout_s, True)
            except (CommandError, CommandAborted) as exc:
                exc.completed = _make_exec((), (), ())  # type: ignore[union-attr]
                raise
            twin = _EXEC_TWIN
            if twin is None:
                return _make_exec(results, commands, (len(results),))
            out = twin()  # _make_exec(...) inline: this return is on the round trip's critical path
            out.messages = results
            out.sent = commands
            out.sizes = (len(results),)
            out.__class__ = ExecResult
            return out  # type: ignore[no-any-return]
        stops = self._stops
        per_command = await self._prepare(commands)
        messages: list[MessageResult] = []
        acked: list[str] = []
        for k, calls in enumerate(per_command):
            if self._stops != stops:  # a stop came while we waited for the previous command's acks
                exc_nb = AbortedBeforeSend(calls[0].skill)
                exc_nb.completed = ExecResult(tuple(messages), commands[:k],  # type: ignore[attr-defined]
                                              tuple(len(c) for c in per_command[:k]))
                raise exc_nb
            sub = self._send(calls)
            try:
                messages.extend(await self._wait(sub, timeout_s, True))
            except ConnectionLost as exc:
                raise _lost(getattr(exc, "reason", "connection lost"), acked=(*acked, *exc.acked),
                            unresolved=exc.unresolved) from exc
            except (CommandError, CommandAborted) as exc:
                exc.completed = ExecResult(tuple(messages), commands[:k],  # type: ignore[union-attr]
                                           tuple(len(c) for c in per_command[:k]))
                raise
            acked.extend(sub.ids)
        return _make_exec(tuple(messages), commands, tuple(len(c) for c in per_command))

    async def _prepare(self, commands: tuple[Command, ...]) -> list[tuple[SkillCall, ...]]:
        """The skill calls of each command (validated), with the connection made ready to send them."""
        try:
            per_command = list(map(_CALLS_OF_COMMAND, commands))  # the common case, in C
        except AttributeError:
            per_command = [_calls_of((c,)) for c in commands]
        if not per_command:
            raise ValueError("commands: at least one command is required")
        if self._state is not _CONNECTED:
            await self._ensure_connected()
        return per_command

    async def cmdexec_joined(self, *commands: Command, timeout_s: float | None = None) -> ExecResult:
        """Write the messages of all commands in ONE write, then await all acks (paper: ``cmdexec_joined``).

        Raises as :meth:`cmdexec`; an error is raised after all acks of the batch are in.
        """
        if timeout_s is not None:
            _check_timeout("timeout_s", timeout_s)
        stops = self._stops
        per_command = await self._prepare(commands)
        calls = list(chain.from_iterable(per_command))
        if not calls:
            raise ValueError("commands: nothing to send")
        if self._stops != stops:
            raise AbortedBeforeSend(calls[0].skill)
        results = await self._wait(self._send(calls), timeout_s, True)
        twin = _EXEC_TWIN
        if twin is None:
            return _make_exec(results, commands, tuple(map(len, per_command)))
        out = twin()  # _make_exec(...) inline, as in cmdexec
        out.messages = results
        out.sent = commands
        out.sizes = tuple(map(len, per_command))
        out.__class__ = ExecResult
        return out  # type: ignore[no-any-return]

    async def stop(self, *, timeout_s: float | None = None) -> MessageResult:
        """Send the ``stop`` skill at once, past whatever is queued (extension; see docs/protocol.md).

        The server aborts the motion in progress, acks every command not yet done ``aborted`` (their waiters
        raise CommandAborted) and then acks the stop ``done``. **Returns** the stop's result only on that ``done``
        ack: its pose is where the robot came to rest. Every other outcome raises; nothing is silent:

        - ``ValueError``: ``timeout_s`` not ``None`` and not a finite number > 0 (nothing is sent).
        - :class:`ConnectError`: the connection was lost, ``auto_reconnect`` is on and the reconnect failed
          (refused at once, or no answer within ``connect_timeout_s``). The stop was not sent.
        - :class:`ConnectionLost`: the connection is lost and ``auto_reconnect`` is off (nothing was sent), or it
          was lost before the ack (with ``auto_reconnect`` the stop is first sent once more on a new connection,
          since a repeated stop cannot move the robot; this is the only message the client ever re-sends).
        - :class:`ClientStateError`: never connected, or closed (also when closed during the reconnect).
        - :class:`AckTimeout`: no ack within ``timeout_s`` (``None``: ``ack_timeout_s``); the robot may still move.
        - :class:`CommandError`: an ``error`` ack, e.g. a server without the extension (the original V+
          AdeptServer halts instead and the stop runs into the timeout).
        - :class:`CommandAborted`: the stop itself was acked ``aborted`` (servers should not do that).

        Its write does not wait for any other call: connected, it is written before this coroutine first yields;
        after a lost connection it is written as soon as the reconnect succeeds. Any command of another call that
        began before this stop and was still waiting to be written (behind a reconnect, or between a cmdexec's
        commands) is never written: that call raises :class:`AbortedBeforeSend`.

        Cancelling the caller does not cancel the stop: it is still written (after a pending reconnect) and its
        ack awaited by a task of the client; a failure nobody awaits any more is logged as an error.
        From synchronous code (a signal handler), use :meth:`stop_nowait`.
        """
        task = self.stop_nowait(timeout_s=timeout_s)
        try:
            return await asyncio.shield(task)
        except asyncio.CancelledError:
            if not task.done():
                task.add_done_callback(_log_orphan_stop)
            raise

    def stop_nowait(self, *, timeout_s: float | None = None) -> asyncio.Task[MessageResult]:
        """:meth:`stop` for synchronous code (e.g. a signal callback; needs a running loop): connected, the stop
        is written before this returns; otherwise the returned task reconnects (``auto_reconnect``) and writes it.

        The task, owned by the client, resolves or fails exactly as :meth:`stop` returns or raises; await it or
        read its result (a failure nobody reads is not logged: that is the caller's business). Cancelling the
        task cancels the wait for the ack, never a write already made. Calls that began before this stop and
        had not yet written their command raise :class:`AbortedBeforeSend`. ValueError for a bad ``timeout_s``.
        """
        if timeout_s is not None:
            _check_timeout("timeout_s", timeout_s)
        self._stops += 1
        sub: Submission | None = None
        if self._state is _CONNECTED:
            try:
                sub = self._send((_STOP,))  # written now, before any await
            except ConnectionLost:
                pass  # the task reconnects (auto_reconnect) or fails with ConnectionLost, as stop() would
        task = asyncio.get_running_loop().create_task(self._stop_flow(sub, timeout_s),
                                                      name=f"RobotClient stop {self.host}:{self.port}")
        self._stop_tasks.add(task)
        task.add_done_callback(self._stop_tasks.discard)
        return task

    async def _stop_flow(self, sub: Submission | None, timeout_s: float | None) -> MessageResult:
        """Reconnect if needed, write the stop (unless already written: ``sub``) and await its ack; once more on
        a new connection if the connection is lost before the ack and ``auto_reconnect`` is on."""
        if sub is None:
            await self._ensure_connected()
            sub = self._send((_STOP,))
        try:
            return (await self._wait(sub, timeout_s))[0]
        except ConnectionLost:
            if not self.auto_reconnect or self._state is _CLOSED or self._state is _NEW:
                raise
            log.warning("connection to %s:%s lost before the stop's ack: sending the stop again on a new "
                        "connection", self.host, self.port)
        await self._ensure_connected()
        return (await self._wait(self._send((_STOP,)), timeout_s))[0]

    async def here(self, *, timeout_s: float | None = None) -> Pose:
        """The robot's current pose (``here`` extension skill), from the server's ack: never a remembered pose.

        Reconnects first like every call (``auto_reconnect``); raises as :meth:`cmdexec` (ConnectError,
        ConnectionLost, ClientStateError, AckTimeout, CommandError; ValueError for a bad ``timeout_s``).
        """
        if timeout_s is not None:
            _check_timeout("timeout_s", timeout_s)
        if self._state is not _CONNECTED:
            await self._ensure_connected()
        return (await self._wait(self._send((_HERE,)), timeout_s, True))[0].ack.pose

    async def hello(self, *, timeout_s: float | None = None) -> tuple[int | None, str]:
        """``(protocol_version, server_name)`` from the ``hello`` extension skill. Raises as :meth:`here`."""
        if timeout_s is not None:
            _check_timeout("timeout_s", timeout_s)
        if self._state is not _CONNECTED:
            await self._ensure_connected()
        ack = (await self._wait(self._send((_HELLO,)), timeout_s, True))[0].ack
        version: int | None
        try:
            version = int(ack.extra[0])
        except (IndexError, ValueError):
            version = None
        return version, (ack.extra[1] if len(ack.extra) > 1 else "")

    # ------------------------------------------------------------------------------------------- observers
    def _notify_send(self, sub: Submission) -> None:
        for mid, call in zip(sub.ids, sub.calls):
            msg = SentMessage(mid, call.skill, call.args, sub.batch, sub.t_send_s)
            for obs in self._observers:
                try:
                    obs.on_send(msg)
                except Exception:
                    log.exception("observer %r failed in on_send", obs)

    # ------------------------------------------------------------------------------------------- observers
    def _notify_ack(self, result: MessageResult) -> None:
        for obs in self._observers:
            try:
                obs.on_ack(result)
            except Exception:
                log.exception("observer %r failed in on_ack", obs)

    def __repr__(self) -> str:
        return f"<RobotClient {self.host}:{self.port} {self._state.value} pending={len(self._pending)}>"


class _AckProtocol(asyncio.Protocol):
    """The default TCP path: bytes go straight from the transport into :meth:`RobotClient._feed`.

    Measured on a 2-core VM, a reader task between the stream and the registry costs one extra loop turn per
    round trip (~10-20 us, about 10 % of a loopback round trip); this protocol routes acks in the transport's own
    callback, as the bare ``readuntil`` client's wake-up does. Connectors that return streams (tests, in-memory
    pairs) use the reader task instead; both feed the same method.
    """

    def __init__(self, client: RobotClient, loop: asyncio.AbstractEventLoop) -> None:
        self._client = client
        self._feed = client._feed
        self._time = client._bind_loop(loop)[1]
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
        if self._client._transport is self._transport:  # never a later connection's business
            self._client._on_lost(exc)


def _settle(sub: Submission, count: int) -> None:
    """``count`` more acks of ``sub`` are in; wake its waiter when that was the last."""
    sub.remaining -= count
    if not sub.remaining and sub._waiter is not None and not sub._waiter.done():
        sub._waiter.set_result(_W_ACKED)


def _lost(reason: str, *, acked: tuple[str, ...] = (), unresolved: tuple[str, ...] = ()) -> ConnectionLost:
    exc = ConnectionLost(reason, acked=acked, unresolved=unresolved)
    exc.reason = reason  # type: ignore[attr-defined]  # the text without the id lists, to re-raise merged
    return exc


_new_submission = object.__new__
_CALLS_OF_COMMAND = operator.attrgetter("_calls")  # Command._calls; AttributeError for anything else
_make_exec = fast_constructor(ExecResult, ("messages", "sent", "sizes"))
_make_result = fast_constructor(MessageResult, ("id", "skill", "args", "batch", "t_send_s", "t_recv_s", "ack"))
# The twins behind _make_ack / _make_result, for _feed's inline build; both or neither (then it calls them).
_ACK_TWIN = getattr(_make_ack, "twin", None)
_RESULT_TWIN = getattr(_make_result, "twin", None) if _ACK_TWIN is not None else None
_EXEC_TWIN = getattr(_make_exec, "twin", None)
_STOP = SkillCall(STOP_SKILL)
_HERE = SkillCall(HERE_SKILL)
_HELLO = SkillCall(HELLO_SKILL)


def _check_timeout(name: str, value: object, *, none_ok: bool = True) -> float | None:
    """``value`` as seconds: ``None`` (if ``none_ok``) or a finite real > 0; else ValueError naming ``name``."""
    if value is None:
        if none_ok:
            return None
        raise ValueError(f"{name}: a number of seconds is required, not None")
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name}: {value!r} is not a number of seconds")
    seconds = float(value)
    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"{name}: {value!r} is not a finite number of seconds > 0")
    return seconds


def _log_orphan_stop(task: asyncio.Task[MessageResult]) -> None:
    """A stop whose caller was cancelled has finished: nobody will read its outcome, so a failure is logged."""
    if task.cancelled():
        log.error("a stop whose caller was cancelled was itself cancelled")
    elif task.exception() is not None:
        log.error("a stop whose caller was cancelled failed: %s", task.exception())


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
