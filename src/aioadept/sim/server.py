"""The asyncio TCP adapter of the simulated controller: sockets, the server clock, timers, the state stream.

It owns everything with I/O and leaves the behaviour to the pure :class:`aioadept.sim.controller.Controller`:

- every chunk read from a client goes through the protocol core's :class:`LineFramer` (V+ READ is not line-framed
  either), each line to :meth:`Controller.handle` with the server time it was read;
- one timer asks :meth:`Controller.step` to run whatever is due next (a break completing, a move getting its slot);
- acks are encoded with :func:`encode_ack` and written to the connection that sent the command;
- a :class:`aioadept.bus.pubsub.Publisher` sends :class:`aioadept.bus.messages.RobotState` on ``robot.state``
  (and, with a world, :class:`aioadept.bus.messages.WorldState` on ``world.state``), driven by the state
  publisher (:class:`aioadept.sim.statepub.StatePublisher`);
- admission (``allow``, ``max_clients``) happens here; a connection over ``max_clients`` and every connection to
  the stop port are served by the stop paths (:class:`aioadept.sim.stoppaths.StopPaths`).

The clock is ``TIMER(-3)``: real seconds since the server started (acks show it with 1 ms resolution). The time
scale speeds up motions only, never this clock. Fault injection (:class:`Faults`) delays acks, drops a connection
after N messages, or makes the server silent, for testing clients against a misbehaving controller; ``raise=POINT``
(for tests only) raises an exception inside the server itself, to test what happens when it has a bug.

When a task of the server dies of an unexpected exception (:meth:`SimServer.die`), nothing is left half alive: the
arm is braked, every connection is closed at once (the clients' pending commands fail with ConnectionLost), the
state stream shows the arm come to rest and then ends, and :attr:`SimServer.dead` is set (``aioadept sim`` exits 1
with one line saying which task died of what, where). What is fatal and what is not: docs/sim.md, "When the server
dies".
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import ipaddress
import itertools
import logging
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any
from dataclasses import dataclass, field

from aioadept.geometry import NULL, Pose
from aioadept.protocol import MAX_LINE, NO_ID, Ack, CommandMessage, ErrorCode, LineFramer, Oversize, encode_ack
from aioadept.robots import model as robot_model
from aioadept.robots.base import DEFAULT_JUMP_LIMIT, JumpLimit, model_joints
from aioadept.sim.controller import Controller, Outgoing
from aioadept.sim.io import HAND_TIME_S, DigitalIO, HandConfig
from aioadept.sim.line import CartesianLimits
from aioadept.sim.stoppaths import READ_SIZE, StopPaths
from aioadept.sim.statepub import MOTION_END_SAMPLE_FAILED, SAMPLE_FAILED, SendFailures, StatePublisher, next_period
from aioadept.world import World
from aioadept.world import WorldConfig

log = logging.getLogger(__name__)

# The defaults of a cell are written once, in aioadept.defaults.
from aioadept.defaults import MAX_QUEUED as DEFAULT_MAX_QUEUED  # noqa: E402
from aioadept.defaults import ROBOT_PORT as DEFAULT_PORT, STATE_ENDPOINT as DEFAULT_STATE_ENDPOINT  # noqa: E402

LINES_PER_TURN = 32
"""Lines of one connection handled before the handler yields to the loop, so every other connection (and the
stop it may carry) is read within a few such turns however fast the others send."""
LINE_MAX_FACTOR = 6
"""A line still incomplete this many line timeouts after its first byte is cut, however its bytes trickle in."""


RAISE_POINTS = {
    "executor": "the executor's timer, as it runs the controller (as if Controller.step raised)",
    "reader": "a connection's reader, on a line it has read (before the controller sees it)",
    "world": "the world's update (World.step, the feeder), wherever it is called from",
    "callback": "a loop callback of the server, outside any guard: the exception reaches asyncio's handler",
    "state-send": "sending a state sample (as if ZeroMQ refused it); every sample while the arm moves",
}
"""The points where ``Faults(raise_at=...)`` (``--fault raise=POINT``) raises: the first time the point is passed
while the arm is moving and a command is in hand (running or queued), so that a test can have the arm moving and
commands pending when the server dies (``state-send``: every sample while the arm moves). For tests of the server's
own death; never in a cell."""


@dataclass(frozen=True, slots=True)
class Faults:
    """Misbehaviour to inject.

    ``ack_delay_s``: every ack is written this much later (order kept). ``drop_after``: a connection is closed by
    the server right after its Nth message has been handled (acks already due are flushed first; its queued
    commands are discarded). ``silent``: commands execute but no ack is ever written. ``raise_at`` (for tests
    only): a bug of the server itself, an :class:`InjectedFault` raised at that point of :data:`RAISE_POINTS`.
    """

    ack_delay_s: float = 0.0
    drop_after: int | None = None
    silent: bool = False
    raise_at: str | None = None

    def __post_init__(self) -> None:
        if self.ack_delay_s < 0:
            raise ValueError("ack_delay_s: must be >= 0")
        if self.drop_after is not None and self.drop_after < 1:
            raise ValueError("drop_after: must be >= 1")
        if self.raise_at is not None and self.raise_at not in RAISE_POINTS:
            raise ValueError(f"raise={self.raise_at}: not a fault point ({', '.join(RAISE_POINTS)})")

    @classmethod
    def parse(cls, specs: Sequence[str]) -> Faults:
        """From CLI words: ``ack-delay=0.5``, ``drop-after=3``, ``silent``, ``raise=POINT``. Raises
        ``ValueError``."""
        delay, drop, silent, raise_at = 0.0, None, False, None
        for spec in specs:
            key, _, value = spec.partition("=")
            if key == "ack-delay":
                delay = float(value)
            elif key == "drop-after":
                drop = int(value)
            elif key == "silent" and not value:
                silent = True
            elif key == "raise":
                raise_at = value
            else:
                raise ValueError(f"unknown fault {spec!r} (ack-delay=S, drop-after=N, silent, raise=POINT)")
        return cls(delay, drop, silent, raise_at)


class InjectedFault(RuntimeError):
    """The exception ``Faults(raise_at=...)`` raises: a stand-in for a bug of the server."""


REST_WAIT_S = 3.0
"""After a death, the longest the state stream goes on to show the braked arm come to rest (a stop from full speed
takes well under this)."""


@dataclass(frozen=True, slots=True)
class SimOptions:
    """Everything ``aioadept sim`` can be told. ``state_endpoint=None`` disables the state stream."""

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    time_scale: float = 1.0
    instant: bool = False
    monitor_speed_pct: float = 100.0
    max_speed_pct: float = 100.0
    jump_limit: JumpLimit | None = DEFAULT_JUMP_LIMIT
    """IK refuses a Cartesian target whose joint motion is out of proportion to its size (wrist flips); None: off."""
    max_clients: int = 16
    max_queued: int = DEFAULT_MAX_QUEUED
    """Commands one connection may have pending (sent and not yet answered, the running one included); each further
    one is refused with SERVER_BUSY (``too many queued commands``) at once. 64, counted the same way, is the shipped
    V+ server's limit (``rs.maxq``), so what works against the sim works against the controller."""
    stop_port: int | None = None
    """The stop port: a second TCP port that serves only ``stop``, ``here`` and ``hello`` (0: a free one; None: no
    stop port). Each connection there is closed once it has had nothing pending for ``stop_window_s``; at most
    ``max_stop_probes`` at once, the oldest without a stop evicted for a newcomer (docs/protocol.md 4.2.1)."""
    allow: tuple[str, ...] = ()
    line_timeout_s: float | None = 10.0
    """A connection in the middle of a line that receives nothing for this long is closed (a peer stuck mid-line);
    a line is also cut if it is still incomplete ``LINE_MAX_FACTOR`` times this long after its first byte
    (slowloris). A client between lines is never timed. None: never."""
    stop_window_s: float = 1.0
    """Over ``max_clients``, a new connection is not refused at once: for this long it may send ``stop`` lines,
    which are executed (the reserved stop path, docs/protocol.md); any other line, or the end of the window, gets
    the SERVER_BUSY refusal and the close."""
    max_stop_probes: int = 64
    """Connections on the reserved stop path at once; when full, the oldest that has not sent a stop is closed to
    make room, so a newcomer always gets its window."""
    keepalive: bool = True
    """TCP keepalive and TCP_USER_TIMEOUT on client sockets, so a vanished peer frees its slot in about 30 s."""
    state_endpoint: str | None = DEFAULT_STATE_ENDPOINT
    state_curve: Any = None
    """CURVE for the state stream (an :class:`aioadept.bus.security.CurveServer`); None: plain (default)."""
    state_rate_hz: float = 100.0
    faults: Faults = field(default_factory=Faults)
    tool: Pose = NULL
    joints_deg: tuple[float, ...] | None = None
    """The joints at start; None: the model's home."""
    robot_model: str = "viper-s850"
    """The arm (:func:`aioadept.robots.model`): its kinematics, limits, speeds and home."""
    hand: HandConfig = HandConfig()
    """Where the hand is wired (valve outputs, closed-fully switch) and its travel time (aioadept.sim.io)."""
    hand_time_s: float = HAND_TIME_S
    """HAND.TIME at start (a V+ program's PARAMETER HAND.TIME changes it)."""
    cartesian_limits: CartesianLimits = field(default_factory=CartesianLimits)
    """What 100 % speed means for a straight line (tool mm/s and deg/s; docs/sim.md)."""
    world: WorldConfig | None = None
    """The parts, feeder and pallet of the cell (aioadept.world; the cell file's [world]); None: no world."""

    def __post_init__(self) -> None:
        arm = robot_model(self.robot_model)  # ValueError naming the known models
        if self.joints_deg is not None:
            model_joints(arm.name, arm.dof, self.joints_deg)  # ValueError: J5, J6 given to a four-axis arm
        if not self.time_scale > 0:
            raise ValueError("time_scale: must be > 0")
        if not 0 < self.monitor_speed_pct <= 100:
            raise ValueError("monitor_speed_pct: must be in (0, 100]")
        if not 0 < self.max_speed_pct <= 100:
            raise ValueError("max_speed_pct: must be in (0, 100]")
        if self.max_clients < 1:
            raise ValueError("max_clients: must be >= 1")
        if self.max_queued < 1:
            raise ValueError("max_queued: must be >= 1")
        if self.stop_port is not None and not 0 <= self.stop_port <= 0xFFFF:
            raise ValueError("stop_port: must be a TCP port number (0..65535) or None")
        if self.line_timeout_s is not None and not self.line_timeout_s > 0:
            raise ValueError("line_timeout_s: must be > 0 or None")
        if not self.stop_window_s > 0:
            raise ValueError("stop_window_s: must be > 0")
        if self.max_stop_probes < 1:
            raise ValueError("max_stop_probes: must be >= 1")
        if not self.state_rate_hz > 0:
            raise ValueError("state_rate_hz: must be > 0")
        for addr in self.allow:
            ipaddress.ip_address(addr)  # ValueError for a malformed address
        if self.faults.raise_at == "world" and self.world is None:
            raise ValueError("fault raise=world needs a world (--world)")
        feeder = self.world.feeder if self.world is not None else None
        if feeder is not None and feeder.sensor == self.hand.closed_switch:
            raise ValueError(f"world feeder sensor {feeder.sensor} is the hand's closed-fully switch; give it "
                             f"another input")

    def make_controller(self) -> Controller:
        """The one robot model these options describe (both sim backends build it here)."""
        return Controller(joints_deg=self.joints_deg, tool=self.tool, monitor_speed_pct=self.monitor_speed_pct,
                          time_scale=self.time_scale, instant=self.instant, max_speed_pct=self.max_speed_pct,
                          jump_limit=self.jump_limit, max_queued_per_conn=self.max_queued,
                          io=DigitalIO(self.hand, hand_time_s=self.hand_time_s),
                          cartesian_limits=self.cartesian_limits,
                          world=None if self.world is None else World(self.world),
                          model=robot_model(self.robot_model))


def _set_keepalive(writer: asyncio.StreamWriter) -> None:
    """Probe idle peers (10 s idle, 5 s interval, 3 probes) and give up on unacknowledged data after 30 s."""
    sock = writer.get_extra_info("socket")
    if sock is None:
        return
    opts = [(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)]
    for name, value in (("TCP_KEEPIDLE", 10), ("TCP_KEEPINTVL", 5), ("TCP_KEEPCNT", 3), ("TCP_USER_TIMEOUT", 30000)):
        if hasattr(socket, name):  # Linux has all four; other systems some
            opts.append((socket.IPPROTO_TCP, getattr(socket, name), value))
    for level, opt, value in opts:
        with contextlib.suppress(OSError):
            sock.setsockopt(level, opt, value)


class _Conn:
    """One client connection and its delayed-ack outbox.

    ``limited``: admitted over ``max_clients`` on the reserved stop path (only ``stop`` is served), or a
    connection to the stop port (``stop``, ``here`` and ``hello``).
    ``idle``: set when the controller has nothing pending for it (waited on before closing a stop probe).
    """

    __slots__ = ("id", "peer", "writer", "outbox", "timer", "messages", "limited", "idle", "stopped", "stop_ids")

    def __init__(self, id: int, peer: str, writer: asyncio.StreamWriter, limited: bool = False) -> None:
        self.id = id
        self.peer = peer
        self.writer = writer
        self.outbox: deque[tuple[float, bytes]] = deque()
        self.timer: asyncio.TimerHandle | None = None
        self.messages = 0
        self.limited = limited
        self.idle: asyncio.Event | None = None
        self.stopped = False  # a stop probe that has sent its stop (never evicted)
        self.stop_ids: set[str] = set()  # its stops not yet answered (the controller does not count them all)


class _StopHost:
    """What the stop paths (:class:`~aioadept.sim.stoppaths.StopPaths`) may do with the server."""

    __slots__ = ("_server",)

    def __init__(self, server: SimServer) -> None:
        self._server = server

    def now(self) -> float:
        return self._server.now()

    def handle(self, item: bytes | CommandMessage, conn: _Conn, now: float) -> None:
        self._server._handle(item, conn, now)

    def reschedule(self) -> None:
        self._server._reschedule()

    def pending(self, conn: _Conn) -> bool:
        return bool(self._server.controller.pending(conn.id))

    def settled(self, conn: _Conn) -> bool:
        return self._server._settled(conn)

    def refusal(self, text: str) -> bytes:
        return self._server._refusal(text)

    def here(self) -> Pose:
        return self._server.controller.here


class SimServer:
    """The simulated RobotServer on TCP. ``async with SimServer(SimOptions(port=0)) as sim: sim.port``.

    ``controller`` is the pure controller it drives (inspect it in tests, register skills on it). ``dead`` is
    set when one of its tasks has died (:meth:`die`); ``death`` then says which, and of what.
    """

    def __init__(self, options: SimOptions | None = None, *, controller: Controller | None = None) -> None:
        if options is None:
            options = SimOptions()
        self.options = options
        self.controller = controller or options.make_controller()
        self.host = options.host
        self.port = options.port
        self.stop_port: int | None = options.stop_port
        self.state_endpoint: str | None = None
        self.connections_total = 0
        self.rejected_total = 0
        self._server: asyncio.base_events.Server | None = None
        self._stop_server: asyncio.base_events.Server | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._t0 = 0.0
        self._wall0 = 0.0
        self._io_cursor = [0]  # the state stream sends each signal change once (robot_state_sample)
        self._world_cursor = [0]  # and each world event once (world_state_sample)
        self._conns: dict[int, _Conn] = {}
        self._handlers: set[asyncio.Task[None]] = set()
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at: float | None = None
        self._publisher = None
        self._state: StatePublisher | None = None
        self._ids = itertools.count(1)
        self._closed = False
        self.death: tuple[str, BaseException] | None = None
        """(the task that died, its exception), once :meth:`die` has been called."""
        self.dead = asyncio.Event()
        self._fault_fired = False
        self._stop_paths = StopPaths(_StopHost(self), options.stop_window_s)
        self._world_error: BaseException | None = None
        self._guard_world()

    # -- lifecycle -----------------------------------------------------------------------------------------
    async def start(self) -> None:
        """Bind, start serving and publishing. ``host``/``port``/``state_endpoint`` then hold the real values."""
        self._loop = asyncio.get_running_loop()
        self._t0 = self._loop.time()
        self._wall0 = time.time()
        if self.options.state_endpoint is not None:
            from aioadept.bus.pubsub import Publisher

            self._publisher = Publisher(self.options.state_endpoint, bind=True, curve=self.options.state_curve)
            self.state_endpoint = self._publisher.actual_endpoint
        try:
            self._server = await asyncio.start_server(self._serve, self.options.host, self.options.port,
                                                      limit=MAX_LINE * 64)
            if self.options.stop_port is not None:
                self._stop_server = await asyncio.start_server(self._serve_stop_port, self.options.host,
                                                               self.options.stop_port, limit=MAX_LINE * 64)
        except BaseException:
            if self._server is not None:
                self._server.close()
            if self._publisher is not None:
                self._publisher.close()
            raise
        sock = self._server.sockets[0].getsockname()
        self.host, self.port = sock[0], sock[1]
        if self._stop_server is not None:
            self.stop_port = self._stop_server.sockets[0].getsockname()[1]
        if self._publisher is not None:
            self._state = StatePublisher(self._publisher, self._samples, self.options.state_rate_hz,
                                         failed=self._state_failed,
                                         send_fault=self.options.faults.raise_at == "state-send")
            self._state.start()

    async def close(self) -> None:
        """Stop serving: close the listener and every connection, cancel timers and tasks, close the publisher."""
        if self._closed:
            return
        self._closed = True
        if self._server is not None:
            self._server.close()
        if self._stop_server is not None:
            self._stop_server.close()
        if self._timer is not None:
            self._timer.cancel()
        if self._state is not None:
            if self.death is not None:
                await self._state.show_rest(self._in_motion, REST_WAIT_S)
            await self._state.stop()
        # Abort the connections rather than cancel their handlers: each handler then sees EOF and returns
        # normally (asyncio's start_server logs handler tasks that end cancelled as errors).
        for conn in list(self._conns.values()):
            if conn.timer is not None:
                conn.timer.cancel()
            conn.writer.transport.abort()
        if self._handlers:
            _, stuck = await asyncio.wait(set(self._handlers), timeout=2.0)
            for t in stuck:
                t.cancel()
            await asyncio.gather(*stuck, return_exceptions=True)
        for server in (self._server, self._stop_server):
            if server is not None:
                with contextlib.suppress(Exception):
                    await server.wait_closed()
        if self._publisher is not None:
            self._publisher.close()

    async def __aenter__(self) -> SimServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def serve_forever(self) -> None:
        """Serve until cancelled."""
        await asyncio.Event().wait()

    # -- death ---------------------------------------------------------------------------------------------
    def die(self, task: str, exc: BaseException) -> None:
        """``task`` died of ``exc`` (an unexpected exception: a bug): brake the arm, run nothing more, close every
        connection at once, stop listening, and set :attr:`dead`. The owner then calls :meth:`close`, which lets
        the state stream show the arm come to rest before it ends. Only the first death counts."""
        if self.death is not None:
            return
        self.death = (task, exc)
        if self._state is not None:
            self._state.halt()
        if self._timer is not None:  # the executor runs nothing more
            self._timer.cancel()
            self._timer = None
        # The sim's stop: the arm decelerates to rest as on a stop, and a deferred OPEN/CLOSE does not act.
        with contextlib.suppress(Exception):  # the model may be what is broken; the rest must still happen
            self.controller.io.pending_hand = None
        try:
            self.controller.trajectory.stop(self.now())
        except Exception:  # noqa: BLE001 - nothing else can stop it; the connections still close
            log.debug("brake failed", exc_info=True)
        for server in (self._server, self._stop_server):
            if server is not None:
                server.close()
        # Abort, not close: the clients learn now (their pending commands fail with ConnectionLost), not after
        # unsent acks of a server that no longer serves.
        for conn in list(self._conns.values()):
            if conn.timer is not None:
                conn.timer.cancel()
                conn.timer = None
            conn.writer.transport.abort()
            if conn.idle is not None:  # a stop probe waiting for its stop's ack: it will never come
                conn.idle.set()
        self.dead.set()

    def on_loop_error(self, loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        """An exception handler for the loop (``loop.set_exception_handler``, as ``aioadept sim`` does): an
        exception that reached asyncio's handler is the server's death. A peer's socket error is none (asyncio
        reports OSError on a transport only in debug mode), nor is anything after :meth:`close`."""
        exc = context.get("exception")
        if exc is None or isinstance(exc, (OSError, asyncio.CancelledError)) or self._closed:
            loop.default_exception_handler(context)
            return
        message = str(context.get("message", ""))
        what = message.removeprefix("Exception in callback ")
        task = context.get("task") or context.get("future")
        if isinstance(task, asyncio.Task):
            what = f"task {task.get_name()}"
        self.die(f"an event loop callback ({what})", exc)

    def _fault(self, point: str) -> None:
        """``Faults(raise_at=point)``: raise here the first time the arm is moving with a command in hand (tests of
        :meth:`die`; :data:`RAISE_POINTS`)."""
        if self.options.faults.raise_at != point or self._fault_fired:
            return
        ctl = self.controller
        if (ctl.busy or ctl.queued()) and ctl.trajectory.in_motion(self.now()):
            self._fault_fired = True
            raise InjectedFault(f"injected {point} fault")

    def _guard_world(self) -> None:
        """Watch the world's update (the I/O's hooks into it: the feeder's step, the hand grasping or releasing).
        It runs inside whatever advances the I/O: a skill (whose exceptions the controller answers as the skill's
        error ack, rightly for a user's skill), the executor or a state sample. A world that fails is the sim's
        model failing, not a skill: the server dies, whoever ran it (``raise=world`` injects it here)."""
        io = self.controller.io
        for name in ("on_advance", "on_drive"):
            hook = getattr(io, name)
            if hook is None:
                continue

            def guarded(*args: Any, _hook: Callable[..., None] = hook) -> None:
                try:
                    self._fault("world")
                    _hook(*args)
                except Exception as exc:
                    if self._world_error is None:
                        self._world_error = exc
                    raise

            setattr(io, name, guarded)

    def _check_world(self, by: str) -> bool:
        """After the controller ran: the world failed inside it (perhaps caught as a skill's error): die."""
        if self._world_error is None:
            return False
        self.die(f"the world's update (run by {by})", self._world_error)
        return True

    def _in_motion(self) -> bool:
        return self.controller.trajectory.in_motion(self.now())

    # -- the clock ----------------------------------------------------------------------------------------
    def now(self) -> float:
        """Server time: seconds since start (V+ ``TIMER(-3)``)."""
        assert self._loop is not None
        return self._loop.time() - self._t0

    @property
    def wall_time_at_start_s(self) -> float:
        return self._wall0

    # -- connections --------------------------------------------------------------------------------------
    def _admit(self, peer_ip: str) -> str | None:
        if self.options.allow and peer_ip not in self.options.allow:
            return "address not allowed"
        if sum(1 for c in self._conns.values() if not c.limited) >= self.options.max_clients:
            return "too many clients"
        return None

    def _refusal(self, text: str) -> bytes:
        now = self.now()
        return encode_ack(Ack.error(NO_ID, ErrorCode.SERVER_BUSY, text, now, now, self.controller.here))

    async def _serve_stop_port(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        await self._serve(reader, writer, stop_port=True)

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, *,
                     stop_port: bool = False) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._handlers.add(task)
        peer = writer.get_extra_info("peername") or ("?", 0)
        refusal = self._admit(str(peer[0]))
        if stop_port and refusal == "too many clients":
            refusal = None  # the stop port has its own limit (max_stop_probes) and never refuses a newcomer
        if (refusal is not None and refusal != "too many clients") or self._closed or self.death is not None:
            # Not on the allow list (or shutting down): refused at once; nothing it sends is read.
            self.rejected_total += 1
            with contextlib.suppress(OSError):
                writer.write(self._refusal(refusal or "closing"))
                await writer.drain()
            writer.close()
            self._handlers.discard(task)
            log.info("refused %s: %s", peer, refusal)
            return
        limited = refusal is not None or stop_port
        if limited:
            # The reserved stop path: a stop must never be refused for "too many clients".
            if not stop_port:
                self.rejected_total += 1
            self._stop_paths.make_room(self._conns.values(), self.options.max_stop_probes)
        conn = _Conn(next(self._ids), f"{peer[0]}:{peer[1]}", writer, limited)
        self._conns[conn.id] = conn
        self.connections_total += 1
        self.controller.connect(conn.id)
        log.info("client %s connected (id %d%s)", conn.peer, conn.id, ", stop only" if limited else "")
        if self.options.keepalive:
            _set_keepalive(writer)
        try:
            if stop_port:
                await self._stop_paths.serve_port(conn, reader, writer)
            elif limited:
                await self._stop_paths.serve_probe(conn, reader, writer)
            else:
                await self._serve_lines(conn, reader, writer)
        except (ConnectionError, OSError) as exc:
            log.info("client %s: %s", conn.peer, exc)
        except Exception as exc:  # noqa: BLE001 - a bug of the reader, the path every line (a stop too) takes
            self.die(f"the reader of client {conn.peer}", exc)
        finally:
            self._conns.pop(conn.id, None)
            if conn.timer is not None:
                conn.timer.cancel()
            if not self._closed and self.death is None:
                try:
                    self.controller.disconnect(conn.id, self.now())
                except Exception as exc:  # noqa: BLE001 - as in _handle: the executor's state is unknown now
                    self.die(f"the executor (as client {conn.peer} left)", exc)
                if not self._check_world(f"the executor, as client {conn.peer} left"):
                    self._reschedule()
            writer.close()
            with contextlib.suppress(Exception):
                await writer.wait_closed()
            self._handlers.discard(task)
            log.info("client %s disconnected", conn.peer)

    async def _serve_lines(self, conn: _Conn, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """An admitted client: every line to the controller, fairly (see READ_SIZE, LINES_PER_TURN)."""
        framer = LineFramer(MAX_LINE)
        drop_after = self.options.faults.drop_after
        line_timeout = self.options.line_timeout_s
        loop = asyncio.get_running_loop()
        line_started = last_byte = 0.0  # loop times of the current incomplete line's first and latest bytes
        while True:
            if line_timeout is None or not framer.in_line:
                data = await reader.read(READ_SIZE)
            else:
                # Only a peer stuck mid-line is timed: from its last byte (slow fragments are fine), and the whole
                # line at most LINE_MAX_FACTOR timeouts (a trickle cannot hold the slot for ever).
                deadline = min(last_byte + line_timeout, line_started + LINE_MAX_FACTOR * line_timeout)
                try:
                    async with asyncio.timeout(max(deadline - loop.time(), 0.0)):
                        data = await reader.read(READ_SIZE)
                except TimeoutError:
                    self._refuse_stalled(conn, writer, line_timeout)
                    return
            if not data:
                return
            was_in_line = framer.in_line
            last_byte = loop.time()
            items = framer.feed(data)
            if framer.in_line and (not was_in_line or items):
                line_started = last_byte  # a new incomplete line began in this chunk
            now = self.now()
            for k, item in enumerate(items):
                if k and k % LINES_PER_TURN == 0:
                    # Let the other connections be read (a stop among them acts now), then go on at the new time.
                    self._reschedule()
                    await asyncio.sleep(0)
                    if conn.id not in self._conns or writer.is_closing():
                        return
                    now = self.now()
                self._fault("reader")
                conn.messages += 1
                self._handle(item, conn, now)
                if self.death is not None:
                    return
                if drop_after is not None and conn.messages >= drop_after:
                    self._reschedule()
                    log.info("fault: dropping %s after %d messages", conn.peer, conn.messages)
                    return
            self._reschedule()
            await writer.drain()
            if len(items) >= LINES_PER_TURN:
                await asyncio.sleep(0)  # a full turn: yield before reading more of this peer's backlog

    def _handle(self, item: bytes | Oversize | CommandMessage, conn: _Conn, now: float) -> None:
        if self.death is not None:
            return
        try:
            out = self.controller.handle(item, conn.id, now)
        except Exception as exc:  # noqa: BLE001
            # The controller's own bug (a skill's is an error ack already): its state is unknown now, a pending
            # break may never be answered and a stop may not act. Serving on would be a server that only looks
            # alive.
            self.die(f"the executor (handling a line from client {conn.peer})", exc)
            return
        if self._check_world(f"the executor, handling a line from client {conn.peer}"):
            return
        self._dispatch(out)

    def _refuse_stalled(self, conn: _Conn, writer: asyncio.StreamWriter, timeout_s: float) -> None:
        now = self.now()
        ack = Ack.error(NO_ID, ErrorCode.MALFORMED_MESSAGE, f"line not completed, nothing received for {timeout_s:g} s",
                        now, now, self.controller.here)
        with contextlib.suppress(OSError):
            writer.write(encode_ack(ack))
        log.info("client %s: incomplete line for %g s, closing", conn.peer, timeout_s)

    # -- acks ---------------------------------------------------------------------------------------------
    def _dispatch(self, out: list[Outgoing]) -> None:
        silent = self.options.faults.silent
        delay = self.options.faults.ack_delay_s
        for o in out:
            conn = self._conns.get(o.conn)  # type: ignore[arg-type]
            if conn is None or conn.writer.is_closing():
                continue
            conn.stop_ids.discard(o.ack.id)
            if silent:
                if conn.idle is not None and self._settled(conn):
                    conn.idle.set()
                continue
            data = encode_ack(o.ack)
            if delay <= 0 and not conn.outbox:
                conn.writer.write(data)
            else:
                conn.outbox.append((self.now() + delay, data))
                self._arm_outbox(conn)
            if conn.idle is not None and self._settled(conn):
                conn.idle.set()

    def _settled(self, conn: _Conn) -> bool:
        """Nothing of ``conn`` is waiting for its ack (its stops included)."""
        return not conn.stop_ids and not self.controller.pending(conn.id)

    def _arm_outbox(self, conn: _Conn) -> None:
        if conn.timer is None and conn.outbox:
            assert self._loop is not None
            conn.timer = self._loop.call_at(self._t0 + conn.outbox[0][0], self._flush_outbox, conn)

    def _flush_outbox(self, conn: _Conn) -> None:
        conn.timer = None
        now = self.now() + 1e-4  # the loop may fire a timer a hair before its time
        while conn.outbox and conn.outbox[0][0] <= now:
            data = conn.outbox.popleft()[1]
            if not conn.writer.is_closing():
                conn.writer.write(data)
        self._arm_outbox(conn)

    # -- the controller's timer ----------------------------------------------------------------------------
    def _reschedule(self) -> None:
        wake = self.controller.next_wake_s()
        if wake == self._timer_at:
            return
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self._timer_at = wake
        if wake is not None and not self._closed and self.death is None:
            assert self._loop is not None
            self._timer = self._loop.call_at(self._t0 + wake, self._on_timer, wake)

    def _on_timer(self, wake: float) -> None:
        self._timer = None
        self._timer_at = None
        if self.death is not None:
            return
        try:
            self._fault("executor")
            # asyncio may run a timer up to one clock tick early; the event is due at its own time.
            out = self.controller.step(max(self.now(), wake))
        except Exception as exc:  # noqa: BLE001 - as in _handle: the executor's state is unknown now
            self.die("the executor", exc)
            return
        if self._check_world("the executor"):
            return
        self._fault("callback")  # outside the guard: what reaches the loop's exception handler
        if out and self._state is not None:
            # A motion ended (or another event was acked): publish the state now, ahead of the acks.
            self._state.publish_now()
        self._dispatch(out)
        self._reschedule()

    # -- state stream -------------------------------------------------------------------------------------
    def robot_state(self):  # -> aioadept.bus.messages.RobotState
        """The state sample for now (what the stream publishes)."""
        return robot_state_sample(self.controller, self.now(), self._wall0, self._io_cursor)

    def world_state(self):  # -> aioadept.bus.messages.WorldState | None
        """The world sample for now (what the stream publishes on ``world.state``), None without a world."""
        return world_state_sample(self.controller, self.now(), self._wall0, self._world_cursor)

    def _samples(self) -> tuple[Any, Any]:
        return self.robot_state(), self.world_state()

    def _state_failed(self, kind: str, exc: BaseException) -> None:
        """The state stream could not compute a sample (the robot model's bug: the server dies of it), or its
        task died."""
        if kind == SAMPLE_FAILED:
            if not self._check_world("the state publisher"):
                self.die("the state publisher (computing a sample)", exc)
        elif kind == MOTION_END_SAMPLE_FAILED:
            if not self._check_world("the executor, sampling the state at a motion's end"):
                self.die("the executor (sampling the state at a motion's end)", exc)
        else:
            self.die("the state publisher", exc)


def robot_state_sample(controller: Controller, now: float, wall0: float,
                       io_cursor: list[int] | None = None):  # -> aioadept.bus.messages.RobotState
    """The state-stream sample of ``controller`` at server time ``now`` (``wall0``: wall time at server time 0).
    Shared by :class:`SimServer` and the V+ emulator backend (``aioadept sim --vplus``).

    ``io_cursor`` (a one-element list, the publisher's own): the sample carries every signal change after
    ``io_cursor[0]``, which moves on, so that each change goes out once, with its own time."""
    from aioadept.bus.messages import RobotState, SignalEvent

    st = controller.state(now)
    program_speed = st.speed_pct * 100.0 / controller.monitor_speed_pct
    io = st.io
    changes: tuple = ()
    if io_cursor is not None:
        new, io_cursor[0] = controller.io.changes_since(io_cursor[0])
        changes = tuple(SignalEvent(c.t_s, c.signal, c.on) for c in new)
    extra = {} if io is None else dict(outputs_on=io.outputs_on, inputs_on=io.inputs_on, soft_on=io.soft_on,
                                       hand=io.hand)
    return RobotState(t_s=now, wall_time_s=wall0 + now, joints_deg=st.joints_deg, pose=st.pose,
                      in_motion=st.in_motion, speed_pct=int(round(program_speed)), air=st.air,
                      changes=changes, **extra)


def world_state_sample(controller: Controller, now: float, wall0: float,
                       cursor: list[int] | None = None):  # -> aioadept.bus.messages.WorldState | None
    """The ``world.state`` sample of ``controller``'s world at server time ``now`` (None without a world): every
    part (a held one where the tool is at ``now``) and the events after ``cursor[0]``, which moves on, so each
    event goes out once. Shared by both backends, as :func:`robot_state_sample`."""
    from aioadept.bus.messages import WorldState

    snap = controller.world_snapshot(now)
    if snap is None:
        return None
    events: tuple = ()
    if cursor is not None:
        assert controller.world is not None
        new, cursor[0] = controller.world.events_since(cursor[0])
        events = tuple(new)
    return WorldState(now, wall0 + now, snap.parts, events, snap.sensors_on)


async def publish_robot_states(publisher: Any, sample: Callable[[], Any], rate_hz: float, *,
                               world_sample: Callable[[], Any] | None = None) -> None:
    """Publish ``sample()`` on ``robot.state`` (and ``world_sample()``, if given, on ``world.state``) at
    ``rate_hz`` until cancelled (the V+ backend's state stream; :class:`SimServer` has its own loop, which
    also tells a model's failure from the stream's). A sample that fails is dropped; failures to send are logged
    once per run of them."""
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, WORLD_STATE_TOPIC

    loop = asyncio.get_running_loop()
    period = 1.0 / rate_hz
    next_t = loop.time()
    failures = SendFailures()

    def send() -> None:
        publisher.publish_nowait(ROBOT_STATE_TOPIC, sample().to_bytes())
        if world_sample is not None:
            world = world_sample()
            if world is not None:
                publisher.publish_nowait(WORLD_STATE_TOPIC, world.to_bytes())

    while True:
        failures.send(send)
        next_t = await next_period(loop, next_t, period)
