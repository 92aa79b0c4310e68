"""RobotClient: the asyncio side of the robot line protocol (the paper's MasterControlNode ↔ RobotServer link).

It sits between the commands (:mod:`aioadept.commands`, values that expand to skill calls) and the TCP connection,
and drives the sans-IO core (:mod:`aioadept.protocol`) over asyncio::

    async with RobotClient("127.0.0.1", 1234) as robot:
        await robot.cmdexec(MoveJoints([0, -90, 180, 0, 90, 0]))          # one command at a time
        res = await robot.cmdexec_joined(SetSpeed(20), MoveToolZ(2.5))     # all messages in one write
        print(res.pose, res.messages[-1].t_recv_s - res.messages[0].t_send_s)

How it works, and the promises it keeps:

- One write path (``RobotClient._send``): the sans-IO registry (:class:`~aioadept.client.PendingCalls`) allocates
  IDs and registers every message of the batch (ID -> submission) *before* the bytes are written, then the batch
  goes out in one write.
- One place routes acks (``PendingCalls.receive``, over the one :class:`~aioadept.protocol.AckReader`): on TCP
  it runs in the transport's ``data_received`` (a
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

Its collaborators, each usable and tested alone: ``client/options.py`` (``ClientOptions``: its settings, one
frozen value), ``client/registry.py`` (``PendingCalls``: the pending-message table, sans-IO),
``client/deadlines.py`` (``DeadlineQueue``: the default-timeout watchdog's queue, sans-IO), ``client/stopport.py``
(the stop on the stop port and its race with the main connection; the side path's sockets), ``client/ready.py``
(``ReadyAttempts``: :meth:`RobotClient.wait_ready`'s schedule, sans-IO) and ``client/transport.py`` (the asyncio
transport). What stays here is the connection's state machine, the write and wait paths (inlined where a round
trip is measured: benchmarks/bench_client.py) and the stop flow.
"""

from __future__ import annotations

import asyncio
import dataclasses
import functools
import logging
import operator
import secrets
import socket
from collections.abc import Awaitable, Callable, Iterable, Sequence
from itertools import chain
from typing import Any

from aioadept import defaults
from aioadept.client.deadlines import DeadlineQueue
from aioadept.client.options import STOP_TIMEOUT_S, ClientOptions
from aioadept.client.ready import ReadyAttempts
from aioadept.client.registry import (
    W_TIMED_OUT as _W_TIMED_OUT,
    PendingCalls,
    Submission,
    calls_of as _calls_of,
    check_timeout as _check_timeout,
    fail_taken,
    lost as _lost,
)
from aioadept.client.results import (
    _EXEC_TWIN,
    ClientState,
    ClientStats,
    ExecResult,
    MessageResult,
    Observer,
    SentMessage,
    _make_exec,
)
from aioadept.client.stopport import STOP_FAILURES, drop_unsent_on_close, open_side_socket, race_stop, stop_on_port
from aioadept.client.transport import AckProtocol, loop_fns, read_loop, set_nodelay, unsent_bytes
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
    TooManyPending,
)
from aioadept.geometry import Pose
from aioadept.protocol import HELLO_SKILL, HERE_SKILL, MAX_ACK_LINE, STOP_SKILL, SkillCall, Status
from aioadept.protocol.robotstatus import STATUS_SKILL, RobotStatus, parse_status_fields

__all__ = ["Connector", "RobotClient"]

log = logging.getLogger("aioadept.client")

Connector = Callable[[], Awaitable[tuple[asyncio.StreamReader, asyncio.StreamWriter]]]
"""An async callable that opens a (reader, writer) pair; the default opens TCP to ``host:port``."""

_CLOSE_FLUSH_S = 1.0
STOP_PORT_AFTER_S = 0.5
""":meth:`RobotClient.stop` also sends the stop on the stop port when the main connection has not answered it this
long after its write: longer than any deceleration ramp (0.1-0.2 s in the sim), far shorter than the stop timeout."""
# Enum member lookups cost ~0.3 us each in 3.11; the hot paths compare against these module constants instead.
_NEW, _CONNECTED, _LOST, _CLOSED = ClientState.NEW, ClientState.CONNECTED, ClientState.LOST, ClientState.CLOSED


_DEFAULT_OPTIONS = ClientOptions()


def _setting(name: str, doc: str) -> property:
    """A setting of the client, read from and written to its :class:`ClientOptions` (checked on every write)."""
    def get(self: RobotClient) -> Any:
        return getattr(self._options, name)

    def set_(self: RobotClient, value: Any) -> None:
        self._set_option(name, value)

    return property(get, set_, doc=doc)


# ---------------------------------------------------------------------------------------------------- client
class RobotClient:
    """An asyncio client of a RobotServer (the V+ AdeptServer, or ``aioadept sim``).

    Reusable (``connect`` again after ``close`` or a lost connection), not reentrant. Options:

    - ``connect_timeout_s``: limit of :meth:`connect` (→ :class:`ConnectError`).
    - ``ack_timeout_s``: default limit of every wait for acks (→ :class:`AckTimeout`); ``None`` waits forever.
      A break waits for the whole motion, so keep this above your longest motion.
    - ``stop_timeout_s``: default limit of :meth:`stop`'s wait for its ack (default 5 s; never ``None``). A stop is
      acked when the arm is at rest, which takes a deceleration ramp (the sim: 0.1 s from full speed, 0.2 s while
      two motions blend), so a stop not acked within seconds means a half-dead server: fail fast, not after
      ``ack_timeout_s``.
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
    - ``stop_side_path`` (opt-in, default ``False``): when :meth:`stop`'s bytes are behind unsent ones (a peer
      that stopped reading), reset the connection (our unsent commands are dropped, never delivered) and send the
      stop first on a new connection, which becomes the client's connection; if that connection cannot be opened
      the stop waits on the old one as before. Caveat: what the server's kernel had already received on the old
      connection is still read by it *after* that stop and may run (TCP delivers it before the reset); see
      docs/protocol.md section 4.4. TCP only (not with ``connector``).
    - ``hello_timeout_s``: after each connect, send ``hello`` and wait this long for its ack; a peer that sends
      nothing parseable back in time (a ZeroMQ port, a silent server) or closes the connection is not a
      RobotServer: :meth:`connect` closes it and raises :class:`NotARobotServer`. An ``error`` ack (the
      ``-406`` "unknown skill" of a server without the extensions) proves a RobotServer and connect goes on.
      ``None`` (the default): no check. Keep it ``None`` for the original V+ AdeptServer, whose task halts on
      any unknown skill (docs/protocol.md section 6). The answer is in :attr:`server_hello`; the exchange is
      not shown to observers.
    - ``stop_port`` (default ``"auto"``: ``port`` + 1, e.g. 1235): the server's stop port, a second TCP port that
      serves only ``stop``, ``here`` and ``hello`` (docs/protocol.md 4.2.1). :meth:`stop` uses it by itself when the
      main connection cannot deliver the stop: lost (and not reconnected), its bytes stuck behind unsent ones, or
      no answer within ``STOP_PORT_AFTER_S``; a second stop cannot move the robot. ``None``: never (a server
      without one, e.g. the original AdeptServer). Not with ``connector``.
    - ``max_pending`` (default 64, :data:`aioadept.defaults.MAX_QUEUED`): at most this many messages waiting for
      their acks on the connection. Both servers admit 64 queued commands per connection and refuse each further
      line with ``-530`` when it is read, so a long pipelined sequence could lose commands in its middle while
      the rest runs. The client refuses such a write whole, before anything is sent
      (:class:`~aioadept.errors.TooManyPending`). A ``stop`` is never refused. ``None``: no limit (a server
      started with a larger ``--max-queued``).
    - ``options``: all of the above as one ``ClientOptions`` (``aioadept.client.options``; then no other
      argument: ``TypeError``). :attr:`options` holds the settings in force; setting one (``robot.ack_timeout_s``)
      checks it as the constructor does.
    """

    def __init__(self, host: str = defaults.ROBOT_HOST, port: int = defaults.ROBOT_PORT, *,
                 connect_timeout_s: float = 5.0, ack_timeout_s: float | None = 60.0,
                 stop_timeout_s: float = STOP_TIMEOUT_S, observers: Iterable[Observer] = (),
                 id_start: int | None = None, auto_reconnect: bool = False,
                 connector: Connector | None = None, max_line: int = MAX_ACK_LINE,
                 hello_timeout_s: float | None = None, stop_side_path: bool = False,
                 max_pending: int | None = defaults.MAX_QUEUED, stop_port: int | str | None = "auto",
                 options: ClientOptions | None = None) -> None:
        given = ClientOptions(host, port, connect_timeout_s, ack_timeout_s, stop_timeout_s, tuple(observers),
                              id_start, auto_reconnect, connector, max_line, hello_timeout_s, stop_side_path,
                              max_pending, stop_port)
        if options is None:
            options = given
        elif given != _DEFAULT_OPTIONS:
            raise TypeError("RobotClient: give either options= or the settings as keywords, not both")
        self._use_options(options)
        self.server_hello: tuple[int | None, str] | None = None
        """``(protocol_version, server_name)`` from the connect-time ``hello`` check; ``None`` without the check
        or from a server that answered it with an error ack (no extensions)."""
        self._connector = options.connector
        self._observers: list[Observer] = list(options.observers)
        self._registry = PendingCalls(
            id_start=secrets.randbits(32) if options.id_start is None else options.id_start,
            max_line=options.max_line)
        self._registry.on_unexpected = self._log_unexpected
        self._probe_lines: list[bytes] | None = None
        """While the connect-time ``hello`` runs: the unexpected lines, kept for the one error instead of logged."""
        self._observers_changed()
        self._deadlines = DeadlineQueue()  # the waits with the default timeout, watched by ONE timer:
        self._watchdog: asyncio.TimerHandle | None = None
        self._state = _NEW
        self._transport: asyncio.BaseTransport | None = None
        self._write: Callable[[bytes], None] | None = None
        self._transport_closed: asyncio.Future[None] | None = None
        self._reader_task: asyncio.Task[None] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._loop_fns: tuple = (None, None, None)  # see _bind_loop
        self._lost_reason: BaseException | None = None
        self._in_context = False
        self._connect_lock: asyncio.Lock | None = None
        self._closes = 0  # close() calls, so a reconnect that raced one does not resurrect the client
        # stop() calls so far: a call that began before a stop and had not yet written its command never writes it
        self._stops = 0
        self._stop_tasks: set[asyncio.Task[MessageResult]] = set()

    @property
    def stats(self) -> ClientStats:
        """Counters of acks and of the unusual (unknown, late, bad lines), kept by the registry."""
        return self._registry.stats

    @property
    def registry(self) -> PendingCalls:
        """The sans-IO registry of pending messages (read its state; the client drives it)."""
        return self._registry

    @property
    def reconnecting(self) -> bool:
        """True while an ``auto_reconnect`` reconnect is in progress (calls wait for it)."""
        return self._connect_lock is not None and self._connect_lock.locked()

    @property
    def options(self) -> ClientOptions:
        """The client's settings now (its ``observers``: those it was made with; see :meth:`add_observer`).
        Setting one of them (``robot.ack_timeout_s = 2``) replaces this value, checked as when it was made."""
        return self._options

    def _use_options(self, options: ClientOptions) -> None:
        self._options = options
        # Read on every round trip: plain attributes, not properties.
        self._connect_timeout_s = options.connect_timeout_s
        self._ack_timeout_s = options.ack_timeout_s
        self._stop_timeout_s = options.stop_timeout_s
        self._max_pending = options.max_pending

    def _set_option(self, name: str, value: Any) -> None:
        self._use_options(dataclasses.replace(self._options, **{name: value}))

    host = _setting("host", "The robot server's host (also named in every error and log line).")
    port = _setting("port", "The robot server's TCP port.")
    connect_timeout_s = _setting("connect_timeout_s",
                                 "Limit of :meth:`connect` and of each reconnect (seconds, finite, > 0).")
    ack_timeout_s = _setting("ack_timeout_s",
                             "Default limit of every wait for acks (seconds, finite, > 0; ``None``: wait forever).")
    stop_timeout_s = _setting("stop_timeout_s",
                              "Default limit of :meth:`stop`'s wait for its ack (seconds, finite, > 0; never None).")
    auto_reconnect = _setting("auto_reconnect", "Reconnect a lost connection before the next new call.")
    stop_side_path = _setting("stop_side_path", "A stop behind unsent bytes goes first on a new connection.")
    hello_timeout_s = _setting("hello_timeout_s", "The connect-time ``hello`` check's limit; ``None``: no check.")
    max_pending = _setting("max_pending", "At most this many messages waiting for their acks (``None``: no limit).")
    stop_port = _setting("stop_port", "The server's stop port: ``\"auto\"`` (``port`` + 1), a number, or ``None``.")

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
        return self._registry.pending_ids

    def add_observer(self, observer: Observer) -> None:
        self._observers.append(observer)
        self._observers_changed()

    def remove_observer(self, observer: Observer) -> None:
        self._observers.remove(observer)
        self._observers_changed()

    async def __aenter__(self) -> RobotClient:
        if self._in_context:
            raise ClientStateError("RobotClient is not reentrant: already inside 'async with'")
        self._in_context = True
        try:
            if self._state is not _CONNECTED:     # wait_ready() may have connected it already
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
        await self._connect()

    async def _connect(self, sock: socket.socket | None = None) -> None:
        """``sock``: an already connected socket to adopt (the stop's side connection): no ``hello`` check then,
        so that the stop is the first line (the sim's reserved stop path serves nothing else)."""
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
                    proto = AckProtocol(self._registry.receive, self._bind_loop(loop)[1], self._on_transport_lost,
                                        loop)
                    if sock is None:
                        transport, _ = await loop.create_connection(lambda: proto, self.host, self.port)
                    else:
                        transport, _ = await loop.create_connection(lambda: proto, sock=sock)
                    write = transport.write  # type: ignore[attr-defined]
                    closed = proto.closed
        except TimeoutError:
            raise ConnectError(f"connect to {self.host}:{self.port}: no answer in {self.connect_timeout_s} s") \
                from None
        except OSError as exc:
            raise ConnectError(f"connect to {self.host}:{self.port}: {exc}") from exc
        set_nodelay(transport)
        self._loop = loop
        self._transport, self._write, self._transport_closed = transport, write, closed
        self._registry.reset()
        self._lost_reason = None
        self._state = _CONNECTED
        if reader is not None:
            self._reader_task = loop.create_task(self._read_loop(reader), name=f"RobotClient reader {self.host}")
        if self.hello_timeout_s is not None and sock is None:
            await self._check_hello(self.hello_timeout_s)

    async def _check_hello(self, timeout_s: float) -> None:
        """The connect-time ``hello`` exchange (``hello_timeout_s``): is the peer a RobotServer at all?"""
        # Observers see the user's traffic only (a run's timing tables must not start with our probe); connect()
        # is awaited before any command of this client is sent, so nothing else is written meanwhile.
        observers, self._observers = self._observers, []
        self._observers_changed()
        self._probe_lines = []
        try:
            self.server_hello = await self.hello(timeout_s=timeout_s)
        except CommandError as exc:  # it speaks the protocol, without the hello extension: go on
            self.server_hello = None
            log.info("robot server %s:%s answered hello with an error (code %s): a server without the "
                     "extensions, going on", self.host, self.port, exc.code)
        except (AckTimeout, ConnectionLost) as exc:
            await self.close()
            self._state = _NEW  # connect() may be called again
            lines = self._probe_lines
            said = _what_answered(lines[0] if lines else self._registry.partial_line(),
                                  closed=isinstance(exc, ConnectionLost))
            raise NotARobotServer(f"{self.host}:{self.port} answered nothing like a RobotServer within "
                                  f"{timeout_s:g} s ({said}): is this the robot's port?") from None
        finally:
            self._probe_lines = None
            self._observers = observers
            self._observers_changed()

    async def close(self) -> None:
        """Close the connection; pending waits fail with ConnectionLost. Idempotent."""
        was = self._state
        self._state = _CLOSED
        self._closes += 1
        if was is _CONNECTED:
            self._registry.fail_all("client closed the connection")
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
    def _feed(self, data: bytes, t_recv: float) -> None:
        """Route every ack in ``data`` (read at loop time ``t_recv``): the registry's ``receive``."""
        self._registry.receive(data, t_recv)

    async def _read_loop(self, reader: asyncio.StreamReader) -> None:
        """The only reader on the streams path (see ``client/transport.py``'s ``read_loop``)."""
        reason = await read_loop(reader, self._registry.receive, self._bind_loop(asyncio.get_running_loop())[1])
        self._on_lost(reason)

    def _on_transport_lost(self, transport: asyncio.BaseTransport | None, exc: BaseException | None) -> None:
        if self._transport is transport:  # never a later connection's business
            self._on_lost(exc)

    def _log_unexpected(self, kind: str, line: bytes, t_recv: float) -> None:
        if self._probe_lines is not None:  # a peer that is no RobotServer: said once, in NotARobotServer
            self._probe_lines.append(line)
            return
        log.warning("robot server %s:%s sent %s: %r", self.host, self.port, kind.replace("_", " "), line[:80])

    def _observers_changed(self) -> None:
        self._registry.on_result = self._notify_ack if self._observers else None

    def _on_lost(self, reason: BaseException | None, *, later: bool = False) -> Callable[[], object] | None:
        """The connection is lost: every pending call fails, at once, or (``later``) when the returned function is
        called; the registry is empty either way. ``None`` when it was not connected."""
        if self._state is not _CONNECTED:
            return None
        self._state = _LOST
        self._lost_reason = reason
        why = f"connection to {self.host}:{self.port} lost" + (f": {reason}" if reason else " (closed by peer)")
        if self._registry.server_error is not None:
            err = self._registry.server_error
            why += f" after the server's error ack: {err.error_message} (code {err.error_code})"
        # During the connect-time hello a loss is reported once, by NotARobotServer.
        log.log(logging.DEBUG if self._probe_lines is not None else logging.WARNING,
                "%s with %d message(s) unacked", why, len(self._registry))
        taken = self._registry.take_all()
        if later:
            return functools.partial(fail_taken, taken, why)
        fail_taken(taken, why)
        return None


    # ------------------------------------------------------------------------------------------- writing
    def _send(self, calls: Sequence[SkillCall], *, futures: bool = False) -> Submission:
        """The one write path: the registry allocates IDs and registers the messages, then one write."""
        if self._state is not _CONNECTED:
            self._raise_not_connected()
        limit = self._max_pending
        if limit is not None and len(self._registry) + len(calls) > limit and calls[0] is not _STOP:
            n = len(self._registry)
            raise TooManyPending(f"{len(calls)} more message(s) would leave {n + len(calls)} pending on "
                                 f"{self.host}:{self.port}; the server admits {limit} per connection "
                                 "(max_pending): nothing was sent", pending=n, wanted=len(calls), limit=limit)
        loop = self._loop
        write = self._write
        assert loop is not None and write is not None
        fns = self._loop_fns
        if fns[0] is not loop:
            fns = self._bind_loop(loop)
        # Registered before the write, so an ack can never beat its entry.
        sub, data = self._registry.register(calls, fns[2] if futures else None)
        sub._owner = self
        sub.t_send_s = fns[1]()
        try:
            write(data)
        except (OSError, ConnectionError, RuntimeError) as exc:
            self._registry.unregister(sub)
            # A transport that refuses a write is broken: the connection is lost (so the next call, and a stop's
            # task, reconnect with auto_reconnect instead of writing into it again).
            self._on_lost(exc)
            if self._transport is not None:
                self._transport.close()
            raise _lost(f"write to {self.host}:{self.port} failed: {exc}", unresolved=tuple(sub.ids)) from exc
        self._registry.stats.messages_sent += len(sub.ids)
        if self._observers:
            self._notify_send(sub)
        return sub

    def _bind_loop(self, loop: asyncio.AbstractEventLoop) -> tuple:
        """``(loop, clock, new_future)`` for ``loop``, remembered (see ``client/transport.py``'s ``loop_fns``)."""
        fns = self._loop_fns = loop_fns(loop)
        return fns


    def _raise_not_connected(self) -> None:
        if self._state is _LOST:
            said = ""
            if self._registry.server_error is not None:
                err = self._registry.server_error
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
                default_s = self._ack_timeout_s
                if timeout_s is None and default_s is not None:
                    if not self._deadlines.push(sub, now + default_s):  # the default changed: a timer of its own
                        sub._timer = loop.call_at(now + default_s, self._time_out, sub)
                    elif self._watchdog is None:
                        self._watchdog = loop.call_at(self._deadlines.next_deadline, self._on_watchdog)
                elif timeout_s is not None:  # a custom timeout: a timer of its own
                    sub._timer = loop.call_at(now + timeout_s, self._time_out, sub)
                why = await waiter
                if why == _W_TIMED_OUT:
                    missing = tuple(mid for mid, r in zip(sub.ids, sub.results, strict=True) if r is None)
                    raise AckTimeout(f"no ack within {default_s if timeout_s is None else timeout_s} s "
                                     f"for {len(missing)} of {len(sub.ids)} message(s) {list(missing)}",
                                     pending=missing)
            if sub._lost_reason is not None and sub.remaining:
                raise _lost(sub._lost_reason,
                            acked=tuple(mid for mid, r in zip(sub.ids, sub.results, strict=True) if r is not None),
                            unresolved=tuple(mid for mid, r in zip(sub.ids, sub.results, strict=True) if r is None))
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

    def _on_watchdog(self) -> None:
        self._watchdog = None
        loop = self._loop
        assert loop is not None
        # the loop may run a timer up to its clock resolution early
        for sub in self._deadlines.due(loop.time() + 0.001):
            self._time_out(sub)
        deadline = self._deadlines.next_deadline
        if deadline is not None:
            self._watchdog = loop.call_at(deadline, self._on_watchdog)

    @staticmethod
    def _time_out(sub: Submission) -> None:
        waiter = sub._waiter
        if waiter is not None and not waiter.done():
            waiter.set_result(_W_TIMED_OUT)

    def _release(self, sub: Submission) -> None:
        """Remove a submission's messages from the registry (idempotent); cancel its timer and futures."""
        if not self._registry.release(sub):
            return
        if sub._timer is not None:
            sub._timer.cancel()
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
        per_command = self._calls_per_command(commands)
        if self._state is not _CONNECTED:
            await self._ensure_connected()
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

    @staticmethod
    def _calls_per_command(commands: tuple[Command, ...]) -> list[tuple[SkillCall, ...]]:
        """The skill calls of each command (validated). A plain function, not a coroutine: a batch's path awaits
        only when the connection must be made ready (``_ensure_connected``); an awaited coroutine costs ~0.07 us
        more than a call, on the path between an ack and the next write."""
        try:
            per_command = list(map(_CALLS_OF_COMMAND, commands))  # the common case, in C
        except AttributeError:
            per_command = [_calls_of((c,)) for c in commands]
        if not per_command:
            raise ValueError("commands: at least one command is required")
        return per_command

    async def cmdexec_joined(self, *commands: Command, timeout_s: float | None = None) -> ExecResult:
        """Write the messages of all commands in ONE write, then await all acks (paper: ``cmdexec_joined``).

        Raises as :meth:`cmdexec`; an error is raised after all acks of the batch are in.
        """
        if timeout_s is not None:
            _check_timeout("timeout_s", timeout_s)
        stops = self._stops
        per_command = self._calls_per_command(commands)
        if self._state is not _CONNECTED:
            await self._ensure_connected()
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
        - :class:`AckTimeout`: no ack within ``timeout_s`` (``None``: ``stop_timeout_s``, 5 s by default, not the
          longer ``ack_timeout_s``: a half-dead server fails the stop fast); the robot may still move.
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
        timeout_s = (self._stop_timeout_s if timeout_s is None
                     else _check_timeout("timeout_s", timeout_s, none_ok=False))
        self._stops += 1
        sub: Submission | None = None
        behind = False
        if self._state is _CONNECTED:
            try:
                sub = self._send((_STOP,))  # written now, before any await
            except ConnectionLost:
                pass  # the task reconnects (auto_reconnect) or fails with ConnectionLost, as stop() would
            else:
                # Bytes still unsent after the stop's write: the stop waits behind them (a peer not reading).
                behind = (self.stop_side_path and self._connector is None and self._transport is not None
                          and unsent_bytes(self._transport) > 0)
        task = asyncio.get_running_loop().create_task(self._stop_flow(sub, timeout_s, behind),
                                                      name=f"RobotClient stop {self.host}:{self.port}")
        self._stop_tasks.add(task)
        task.add_done_callback(self._stop_tasks.discard)
        return task

    async def _stop_flow(self, sub: Submission | None, timeout_s: float | None,
                         behind: bool = False) -> MessageResult:
        """Reconnect if needed, write the stop (unless already written: ``sub``) and await its ack; once more on
        a new connection if the connection is lost before the ack and ``auto_reconnect`` is on. ``behind``: the
        written stop sits behind unsent bytes: try the side path (:meth:`_stop_side`) first. Wherever the main
        connection cannot deliver the stop, the stop port does (:meth:`_stop_port_race`)."""
        if sub is not None and behind:
            if self.stop_side_path:
                side = await self._stop_side(sub, timeout_s)
                if side is not None:
                    sub = side
            elif self._stop_port_number() is not None:
                # the peer does not read this connection: the stop port now, not after STOP_PORT_AFTER_S
                return await self._stop_port_race(sub, timeout_s, 0.0)
        if sub is None:
            try:
                await self._ensure_connected()
                sub = self._send((_STOP,))
            except (ConnectError, ConnectionLost) as exc:
                return await self._stop_port_instead(exc, timeout_s)
        try:
            return await self._stop_port_race(sub, timeout_s, STOP_PORT_AFTER_S)
        except ConnectionLost as exc:
            if self._state is _CLOSED or self._state is _NEW:
                raise
            if not self.auto_reconnect:
                return await self._stop_port_instead(exc, timeout_s)
            log.warning("connection to %s:%s lost before the stop's ack: sending the stop again on a new "
                        "connection", self.host, self.port)
        try:
            await self._ensure_connected()
        except ConnectError as exc:
            return await self._stop_port_instead(exc, timeout_s)
        return (await self._wait(self._send((_STOP,)), timeout_s))[0]

    def _stop_port_number(self) -> int | None:
        return self._options.stop_port_number

    async def _stop_port_instead(self, exc: BaseException, timeout_s: float) -> MessageResult:
        """The main connection cannot carry the stop (``exc``): send it on the stop port; if that fails too, the
        main connection's error is what the caller gets (with the stop port's in the log)."""
        if self._stop_port_number() is None:
            raise exc
        log.warning("stop: %s; sending it on the stop port %s:%s", exc, self.host, self._stop_port_number())
        try:
            return await self.stop_on_stop_port(timeout_s=timeout_s)
        except STOP_FAILURES as side:
            log.error("stop on the stop port %s:%s failed too: %s", self.host, self._stop_port_number(), side)
            raise exc from side

    async def _first_result(self, sub: Submission, timeout_s: float) -> MessageResult:
        return (await self._wait(sub, timeout_s))[0]

    async def _stop_port_race(self, sub: Submission, timeout_s: float, after_s: float) -> MessageResult:
        """Await the stop written on the main connection; if no ack has come ``after_s`` after its write, send it
        on the stop port as well (``race_stop`` in ``client/stopport.py``)."""
        side = None
        if self._stop_port_number() is not None:
            def side() -> Awaitable[MessageResult]:
                return self.stop_on_stop_port(timeout_s=timeout_s)
        return await race_stop(self._first_result(sub, timeout_s), side, after_s, peer=f"{self.host}:{self.port}")

    async def stop_on_stop_port(self, *, timeout_s: float | None = None) -> MessageResult:
        """Send ``stop`` on the server's stop port (a connection of its own, closed after the ack) and return its
        result on the ``done`` ack. For when the main connection cannot carry it, e.g. every client slot of the
        server is taken: :meth:`stop` calls it by itself; ``aioadept send stop`` too when it cannot connect.
        Works on a client that was never connected (only ``host`` and the stop port are used).

        Raises :class:`ClientStateError` without a stop port (``stop_port=None``, or a ``connector``),
        :class:`ConnectError` if the port cannot be reached or closes without answering, :class:`AckTimeout`
        (``timeout_s``; default ``stop_timeout_s``), :class:`CommandError` / :class:`CommandAborted` for an error
        or aborted ack. Observers see the stop and its ack like any other message.
        """
        port = self._stop_port_number()
        if port is None:
            raise ClientStateError(f"no stop port for {self.host}:{self.port} (stop_port=None or a connector)")
        timeout_s = (self._stop_timeout_s if timeout_s is None
                     else _check_timeout("timeout_s", timeout_s, none_ok=False))
        return await stop_on_port(self.host, port, timeout_s, on_send=self._notify_sent, on_ack=self._notify_ack)

    async def _stop_side(self, sub: Submission, timeout_s: float) -> Submission | None:
        """The stop is behind unsent bytes on a peer that is not reading: open a fresh connection (the sim's
        reserved stop path admits it even when the server is full); once it is open, reset the old one, so that its
        unsent bytes (commands written before the stop) never reach the server, and write the stop first on the new
        one, which becomes the client's connection. Returns the new stop's submission, or ``None`` when the side
        connection cannot be opened (refused, or no answer in time): the stop already written on the old connection
        then stands alone, untouched (a one-client server without the reserved path is not harmed)."""
        transport = self._transport
        try:
            side = await open_side_socket(self.host, self.port, min(self._connect_timeout_s, timeout_s))
        except (OSError, TimeoutError) as exc:
            log.warning("stop behind unsent bytes to %s:%s; side connection failed (%s): the stop waits on the "
                        "old connection", self.host, self.port, exc)
            return None
        if self._transport is not transport or self._state is not _CONNECTED or sub.done():
            side.close()  # the old connection ended (or the stop was acked) meanwhile: its outcome stands
            return None
        log.warning("stop behind unsent bytes to %s:%s: resetting the connection (unsent commands are dropped) "
                    "and sending the stop on a new one", self.host, self.port)
        if transport is not None:
            drop_unsent_on_close(transport)
        # The old connection's calls fail after the stop is written: failing tens of thousands of them (a
        # ConnectionLost each) takes 0.4 s on an idle core, seconds on a loaded one, which the stop must not wait for.
        fail_old = self._on_lost(ConnectionResetError("reset by the client: a stop was behind unsent bytes"),
                                 later=True)
        try:
            if transport is not None:
                transport.abort()  # type: ignore[attr-defined]
            try:
                await self._connect(sock=side)
            except BaseException:
                side.close()
                raise
            return self._send((_STOP,))
        finally:
            if fail_old is not None:
                fail_old()

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

    async def status(self, *, timeout_s: float | None = None) -> RobotStatus:
        """The robot's status from the ``status`` extension skill (docs/protocol.md, section 4.7): moving, the
        program speed, the last error (code and text), high power and E-stop where the server knows them.

        Raises as :meth:`here`; :class:`~aioadept.errors.RemoteProtocolError` if the ack carries no status.
        """
        if timeout_s is not None:
            _check_timeout("timeout_s", timeout_s)
        if self._state is not _CONNECTED:
            await self._ensure_connected()
        ack = (await self._wait(self._send((_STATUS,)), timeout_s, True))[0].ack
        return parse_status_fields(ack.extra)

    async def wait_ready(self, timeout_s: float, *, max_backoff_s: float = 1.0) -> tuple[int | None, str]:
        """Connect, retrying with backoff until the server answers ``hello``: start the app before the controller.

        Each attempt connects (refused, unreachable, or no answer within ``connect_timeout_s``) and sends
        ``hello`` (no answer within ``min(2 s, time left)``: a server still starting); a failed attempt closes its
        connection and the next one follows after 0.05 s, doubling up to ``max_backoff_s``. Returns
        ``(protocol_version, server_name)`` as :meth:`hello` does, or ``(None, "")`` from a server that refuses
        ``hello`` with an error ack (it speaks the protocol without the extensions). Already connected: one
        ``hello``. Raises :class:`~aioadept.errors.ConnectError` naming the last failure when ``timeout_s`` has
        passed, ``ValueError`` for a ``timeout_s``/``max_backoff_s`` that is not a finite number > 0. Then
        ``async with robot:`` uses the connection it made::

            robot = RobotClient(host, port)
            await robot.wait_ready(120)       # the controller may still be booting
            async with robot:
                await robot.cmdexec(...)
        """
        _check_timeout("timeout_s", timeout_s, none_ok=False)
        _check_timeout("max_backoff_s", max_backoff_s, none_ok=False)
        loop = asyncio.get_running_loop()
        tries = ReadyAttempts(f"{self.host}:{self.port}", timeout_s, max_backoff_s, loop.time())
        while True:
            left = tries.begin(loop.time())
            try:
                async with asyncio.timeout(left):
                    if self._state is not _CONNECTED:
                        await self._connect()
                    return await self.hello(timeout_s=min(_READY_HELLO_S, left))
            except CommandError:
                return None, ""
            except (ConnectError, ConnectionLost, AckTimeout, NotARobotServer, TimeoutError) as exc:
                tries.failed(exc, connected=self._state is _CONNECTED)
                if self._state is _CONNECTED:
                    await self.close()
                self._state = _NEW    # connect() may be called again (as after a failed hello check)
            await asyncio.sleep(tries.pause(loop.time()))

    # ------------------------------------------------------------------------------------------- observers
    def _notify_send(self, sub: Submission) -> None:
        for mid, call in zip(sub.ids, sub.calls, strict=True):
            self._notify_sent(SentMessage(mid, call.skill, call.args, sub.batch, sub.t_send_s))

    def _notify_sent(self, msg: SentMessage) -> None:
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
        return f"<RobotClient {self.host}:{self.port} {self._state.value} pending={len(self._registry)}>"



_CALLS_OF_COMMAND = operator.attrgetter("_calls")  # Command._calls; AttributeError for anything else
_STOP = SkillCall(STOP_SKILL)
_HERE = SkillCall(HERE_SKILL)
_HELLO = SkillCall(HELLO_SKILL)
_STATUS = SkillCall(STATUS_SKILL)
_READY_HELLO_S = 2.0
"""How long :meth:`RobotClient.wait_ready` waits for one attempt's ``hello`` answer."""


def _log_orphan_stop(task: asyncio.Task[MessageResult]) -> None:
    """A stop whose caller was cancelled has finished: nobody will read its outcome, so a failure is logged."""
    if task.cancelled():
        log.error("a stop whose caller was cancelled was itself cancelled")
    elif task.exception() is not None:
        log.error("a stop whose caller was cancelled failed: %s", task.exception())


_ZMTP_SIGNATURE_END = 0x7F  # a ZeroMQ peer's greeting: 0xFF, 8 bytes, 0x7F (ZMTP 3.x, rfc.zeromq.org/spec/23)


def _what_answered(first: bytes, *, closed: bool) -> str:
    """What a peer that is no RobotServer did, for :class:`NotARobotServer`'s one line: its first bytes, named
    when they are a ZeroMQ greeting or HTTP."""
    if not first:
        return "it closed the connection without a word" if closed else "it sent nothing"
    said = f"it sent {first[:40]!r}"
    if first[:1] == b"\xff" and len(first) >= 10 and first[9] == _ZMTP_SIGNATURE_END:
        said += ": a ZeroMQ greeting"
    elif first.lstrip().lower().startswith((b"http/", b"<!doctype html", b"<html")):
        said += ": an HTTP server"
    return said + ("; then it closed the connection" if closed else "")
