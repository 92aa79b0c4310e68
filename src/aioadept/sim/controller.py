"""The simulated SmartController running AdeptServer: skills, one serial executor, V+ motion semantics.
It is the one robot model both backends drive: the queue, the executor, forward processing, the stop path, the
acks and the motion generators (joint and straight-line) share its state; the skill table, the timing and the
line planning live in skills.py, motion.py and line.py.

Pure: no sockets, no clock. The TCP adapter (:mod:`aioadept.sim.server`) feeds it lines with the time they were
read and calls :meth:`Controller.step` when :meth:`Controller.next_wake_s` says something is due; tests do the
same with a fake clock. Each call returns the acks to write, each addressed to the connection that sent the command::

    ctl = Controller()
    ctl.connect("a")
    out = ctl.handle(b"0000abcd:move_joints:0,-90,180,0,90,0", "a", now=0.0)   # [Outgoing("a", Ack(...done...))]
    out = ctl.handle(b"0000abce:break", "a", now=0.0)                           # [] - waits for the motion
    out = ctl.step(ctl.next_wake_s())                                          # [Outgoing("a", break done)]

Semantics, following the original V+ AdeptServer (docs/protocol.md):

- One executor runs skills one after another in arrival order, across all connections, like the single V+ task
  running ``CALLS $skill``. While a skill waits (``break`` for the robot to stop, a move for a free slot), later
  commands wait behind it.
- Forward processing is one motion deep: a move acks when its motion starts. The first of ``MOVE a; MOVE b;
  BREAK`` acks at once; ``b`` waits (holding the executor, as the V+ task waits in its ``MOVE``) until ``a``
  begins to decelerate, where ``b`` blends in, and acks then; ``BREAK`` acks when ``b`` has completed.
- ``set_speed`` applies to the next motion instruction only (V+ ``SPEED`` without ``ALWAYS``), which consumes it
  whether it succeeds or fails. Effective speed = program speed x monitor speed / 100, capped at
  ``max_speed_pct`` (a safety limit of the cell, docs/security.md; 100 = no cap).
- Relative moves read ``HERE`` when they run, as the V+ program does: without a ``break`` before them they start
  from wherever the arm is at that moment, not from the previous motion's target.
- Errors never halt the server: a bad line, unknown skill, wrong argument count or value, unreachable target or
  joint limit each answer an ``error`` ack with a code from :class:`aioadept.protocol.ErrorCode`; the robot does
  not move and the next command runs.
- ``stop`` (an extension) is served the moment it is read: the executing skill and every queued command, from
  every connection, are acked ``aborted``; the arm decelerates to rest; then ``stop`` is acked ``done``.
- ``hello`` (an extension): its ack carries two trailing fields, the protocol version and the server name
  (``1:aioadept-sim 0.1.0``), as docs/protocol.md specifies.
- Read-only queries (``here``, ``hello``) from a connection with nothing pending are answered the moment they are
  read, from the current state, as the V+ server's reader task would: they never wait behind another client's
  motion. From a connection with commands pending they run in turn, so order within a connection is kept.
- Three stops in a row each get ``done`` once the arm is at rest: a stop never aborts another stop.
- A connection that goes away loses its queued commands and a skill of its that is still waiting (a move for its
  slot): they never run. Motions it already started go on.
- With a world (:mod:`aioadept.world`, ``world=``), the hand's valves grasp and release its parts at the
  tool's pose (:meth:`Controller._hand_drive`) and its feeder sensor drives an input, whichever backend switched
  them.
- Values are checked before anything moves: set_speed within [``min_speed_pct``, 100], pose rotations within
  +-360 deg, joint values within +-3600 deg (then the joint limits), positions within +-10 m; a second message
  with an ID still pending on the same connection is refused (``stop`` excepted: it is never refused).

Skills live in a table (:attr:`Controller.skills`, from :mod:`aioadept.sim.skills`); :meth:`Controller.register`
adds user skills. A skill is a
function ``skill(ctl, args)`` that returns ``None`` (done now), a :class:`SkillResult` (done, with trailing
fields), or a generator that yields the server time it wants to be resumed at and finally returns one of those.
It raises :class:`aioadept.errors.RobotError` to answer an ``error`` ack.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from collections.abc import Generator, Hashable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from aioadept.errors import RemoteProtocolError, RobotError
from aioadept.geometry import NULL, Pose
from aioadept.protocol import (
    NO_ID,
    STOP_SKILL,
    Ack,
    CommandMessage,
    ErrorCode,
    Oversize,
    Status,
    parse_command,
    recover_id,
)
from aioadept.robots import RobotModel
from aioadept.robots.base import DEFAULT_JUMP_LIMIT, ConfigRequest, JointLimits, JumpLimit, model_joints
from aioadept.robots.viper import VIPER_S850
from aioadept.sim.io import DigitalIO, HandState, IoSnapshot
from aioadept.sim.line import CartesianLimits, LinePath, plan_tool_line
from aioadept.sim.motion import MotionLimits, Trajectory
from aioadept.world import World
from aioadept.world import WorldEvent, WorldSnapshot

from aioadept.sim.skills import (_STOP_RUN, AIR_SIGNAL, MIN_SPEED_PCT, SkillFunc, SkillGen, SkillResult, SkillSpec,
                                 default_skills)

ConnId = Hashable
log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class Outgoing:
    """An ack to write to one connection."""

    conn: ConnId
    ack: Ack


@dataclass(slots=True)
class _Entry:
    conn: ConnId
    id: str
    t_read_s: float
    spec: SkillSpec | None = None
    args: tuple[float, ...] = ()
    error: tuple[int, str | None] | None = None
    tracked: bool = False  # its ID is in the connection's in-flight set until it is answered


@dataclass(slots=True)
class _Running:
    entry: _Entry
    t_start_s: float
    gen: SkillGen
    wake_s: float


@dataclass(frozen=True, slots=True)
class ControllerState:
    """A snapshot of the robot for the state stream (see docs/interfaces.md)."""

    t_s: float
    joints_deg: tuple[float, ...]
    pose: Pose
    in_motion: bool
    speed_pct: float
    air: bool
    io: IoSnapshot | None = None  # the signals that are on and the hand (aioadept.sim.io)


class Controller:
    """The simulated controller; see the module docstring. All times are server-clock seconds."""

    def __init__(self, *, joints_deg: Sequence[float] | None = None, tool: Pose = NULL,
                 monitor_speed_pct: float = 100.0, time_scale: float = 1.0, instant: bool = False,
                 motion_limits: MotionLimits | None = None, joint_limits: JointLimits | None = None,
                 max_queued_per_conn: int = 10_000, skills: Iterable[SkillSpec] | None = None,
                 version: str | None = None, max_speed_pct: float = 100.0,
                 min_speed_pct: float = MIN_SPEED_PCT,
                 jump_limit: JumpLimit | None = DEFAULT_JUMP_LIMIT, io: DigitalIO | None = None,
                 cartesian_limits: CartesianLimits | None = None, world: World | None = None,
                 model: RobotModel = VIPER_S850) -> None:
        self.model = model
        """The arm (:mod:`aioadept.robots`): its kinematics, and the defaults of the joints (its home), the joint
        limits and the joint speeds."""
        joints_deg = model.home_deg if joints_deg is None else model_joints(model.name, model.dof, joints_deg)
        joint_limits = model.limits if joint_limits is None else joint_limits
        if motion_limits is None:
            motion_limits = MotionLimits(model.max_speed_deg_s)
        if not 0 < monitor_speed_pct <= 100:
            raise ValueError(f"monitor_speed_pct: {monitor_speed_pct} outside (0, 100]")
        if not 0 < max_speed_pct <= 100:
            raise ValueError(f"max_speed_pct: {max_speed_pct} outside (0, 100]")
        if not 0 < min_speed_pct <= 100:
            raise ValueError(f"min_speed_pct: {min_speed_pct} outside (0, 100]")
        self.min_speed_pct = float(min_speed_pct)
        self.jump_limit = jump_limit
        """Cartesian targets whose joint motion is out of proportion to their size are refused (JOINT_JUMP,
        docs/sim.md); None turns the check off."""
        """The lowest program speed set_speed accepts (a motion at 0.001 % would hold the executor for days)."""
        joint_limits.check(joints_deg)
        self.tool = tool
        self.monitor_speed_pct = float(monitor_speed_pct)
        self.max_speed_pct = float(max_speed_pct)
        """Cap on the effective speed, whatever the program and monitor speeds ask for."""
        self.joint_limits = joint_limits
        self.trajectory = Trajectory(joints_deg, limits=motion_limits, time_scale=time_scale, instant=instant,
                                     cartesian=cartesian_limits)
        self.max_queued_per_conn = max_queued_per_conn
        self.always_speed_pct = 100.0
        self.pending_speed_pct: float | None = None
        self.accel_pct = 100.0
        self.config_request: ConfigRequest | None = None
        """V+ LEFTY/RIGHTY/ABOVE/BELOW/FLIP/NOFLIP/SINGLE: the configuration the next motion to a pose ends in
        (:meth:`request_config`); consumed by the next motion instruction, as a one-shot SPEED."""
        self.always_duration_s = 0.0
        self.pending_duration_s: float | None = None
        """V+ DURATION [ALWAYS]: the least time (s, robot time) of the next (every) motion."""
        self.io = (io or DigitalIO()).scaled(time_scale, instant)  # digital I/O and the hand: the one model
        self.signals = self.io.values  # signal states by number: read them; change them through self.io
        self.world = world
        """The parts the hand grasps and the feeder sensor drives (aioadept.world), or None: no world."""
        if world is not None:
            self.io.on_drive = self._hand_drive
            world.time_scale = time_scale
            self._apply_world_events([e for e in world.events if e.kind == "sensor"], 0.0)
        self.now_s = 0.0
        """The time of the event being processed (a skill reads it as 'now')."""
        if version is None:
            from aioadept import __version__ as version
        self.version = version
        self.skills: dict[str, SkillSpec] = {}
        for spec in default_skills() if skills is None else skills:
            self.skills[spec.name] = spec
        self._queue: deque[_Entry] = deque()
        self._queued_by_conn: dict[ConnId, int] = {}
        # Per connection, the IDs queued or executing (not yet answered) and how many of each: NO_ID lines (broken
        # ones, answered in turn) may repeat; any other ID may not.
        self._inflight: dict[ConnId, dict[str, int]] = {}
        self._running: _Running | None = None
        self._conns: set[ConnId] = set()
        self._out: list[Outgoing] = []
        self._fk_cache: tuple[tuple[float, ...], Pose, Pose] | None = None  # (joints, tool, pose) of the last FK
        self.executed = 0
        """Skills run to completion (done or error), for inspection in tests and benchmarks."""
        if world is not None:  # last: the feeder's step reads the arm's pose (HERE)
            self.io.on_advance = self._world_step
        self.last_error: tuple[int, str] = (0, "")
        """Code and text of the last skill that failed (0, "": none), as the ``status`` skill reports it."""

    # -- skill table ---------------------------------------------------------------------------------------
    def register(self, name: str, func: SkillFunc, *, nargs: int | Sequence[int] | None = 0,
                 immediate: bool = False, readonly: bool = False) -> None:
        """Add or replace a skill. ``nargs``: an accepted argument count, several, or None for any.
        ``immediate``/``readonly``: see :class:`SkillSpec`."""
        from aioadept.protocol import check_skill_name

        check_skill_name(name)
        counts = None if nargs is None else ((nargs,) if isinstance(nargs, int) else tuple(nargs))
        self.skills[name] = SkillSpec(name, func, counts, immediate, readonly)

    # -- connections ---------------------------------------------------------------------------------------
    def connect(self, conn: ConnId) -> None:
        self._conns.add(conn)

    def disconnect(self, conn: ConnId, now: float | None = None) -> None:
        """Forget a connection: its queued commands are discarded and never run; a skill of its that is waiting
        (a move for its motion slot, a break) is dropped too, so no motion of its starts after this. Motions it
        already started go on.

        The queue is dropped *before* the controller advances to ``now``: advancing first would start, at their
        due times up to ``now``, commands of a client that is already gone.
        """
        self._conns.discard(conn)
        self._queue = deque(e for e in self._queue if e.conn != conn)
        self._queued_by_conn.pop(conn, None)
        self._inflight.pop(conn, None)
        run = self._running
        if run is not None and run.entry.conn == conn:
            run.gen.close()
            self._running = None
        if now is not None:
            self._advance(now)

    @property
    def connections(self) -> frozenset[ConnId]:
        return frozenset(self._conns)

    def queued(self, conn: ConnId | None = None) -> int:
        """Commands waiting to run (of one connection, or all)."""
        return len(self._queue) if conn is None else self._queued_by_conn.get(conn, 0)

    def pending(self, conn: ConnId) -> int:
        """Commands of ``conn`` not yet answered (queued or executing)."""
        return sum(self._inflight.get(conn, {}).values())

    @property
    def busy(self) -> bool:
        """True while a skill is executing (e.g. a break waiting)."""
        return self._running is not None

    # -- input ---------------------------------------------------------------------------------------------
    def handle(self, message: bytes | Oversize | CommandMessage, conn: ConnId, now: float) -> list[Outgoing]:
        """Take one framed line (or its parsed message) read from ``conn`` at ``now``; return acks now due."""
        self._advance(now)
        entry = self._entry(message, conn, now)
        spec = entry.spec
        inflight = self._inflight.get(conn)
        if entry.error is None and spec is not None and spec.name == STOP_SKILL:
            # Never refused, not even for a duplicate ID: a stop that does not arrive is the worst outcome.
            self._stop(entry, now)
        elif inflight and entry.id != NO_ID and entry.id in inflight:
            # Its ack could not be told from the pending one's; refuse it before it can run.
            self._emit(entry, Status.ERROR, now, now,
                       (ErrorCode.MALFORMED_MESSAGE, f"message ID {entry.id} is still pending on this connection"))
        elif entry.error is None and spec is not None and (spec.immediate or (spec.readonly and not inflight)):
            self._run_immediate(entry, now)
        elif self.pending(conn) >= self.max_queued_per_conn:
            # counted as the V+ server and RobotClient(max_pending) count: sent and not yet answered, the running
            # command included (a stop is never counted: it is never refused)
            self._emit(entry, Status.ERROR, now, now, (ErrorCode.SERVER_BUSY, "too many queued commands"))
        else:
            self._enqueue(entry)
        self._advance(now)
        return self._drain()

    def _enqueue(self, entry: _Entry) -> None:
        self._queue.append(entry)
        conn = entry.conn
        self._queued_by_conn[conn] = self._queued_by_conn.get(conn, 0) + 1
        ids = self._inflight.setdefault(conn, {})
        ids[entry.id] = ids.get(entry.id, 0) + 1
        entry.tracked = True

    def step(self, now: float) -> list[Outgoing]:
        """Run everything due up to ``now``; return the acks produced."""
        self._advance(now)
        return self._drain()

    def next_wake_s(self) -> float | None:
        """When :meth:`step` next has work (None: nothing until a new message arrives)."""
        if self._running is not None:
            return self._running.wake_s
        return None

    def _entry(self, message: bytes | Oversize | CommandMessage, conn: ConnId, now: float) -> _Entry:
        if isinstance(message, Oversize):
            return _Entry(conn, recover_id(message.head) or NO_ID, now,
                          error=(ErrorCode.LINE_TOO_LONG, "line longer than 128 characters"))
        if not isinstance(message, CommandMessage):
            try:
                message = parse_command(bytes(message))
            except RemoteProtocolError as exc:
                return _Entry(conn, exc.id or NO_ID, now, error=(exc.code, exc.message))
        spec = self.skills.get(message.skill)
        if spec is None:
            return _Entry(conn, message.id, now, error=(ErrorCode.UNKNOWN_SKILL, f"undefined skill {message.skill}"))
        if spec.nargs is not None and len(message.args) not in spec.nargs:
            want = " or ".join(map(str, spec.nargs))
            return _Entry(conn, message.id, now, error=(
                ErrorCode.WRONG_ARGUMENT_COUNT, f"{spec.name} takes {want} arguments, got {len(message.args)}"))
        return _Entry(conn, message.id, now, spec, tuple(float(a) for a in message.args))

    # -- executor ------------------------------------------------------------------------------------------
    def _advance(self, now: float) -> None:
        """Process every event due up to ``now``, each at its own time."""
        for _ in range(1_000_000):  # a bound, so a skill that keeps yielding the past cannot hang the server
            run = self._running
            if run is not None:
                if run.wake_s > now:
                    break
                self._resume(run, max(run.wake_s, self.now_s))
                continue
            if not self._queue:
                break
            entry = self._queue.popleft()
            n = self._queued_by_conn.get(entry.conn, 1) - 1
            if n:
                self._queued_by_conn[entry.conn] = n
            else:
                self._queued_by_conn.pop(entry.conn, None)
            t = max(self.now_s, entry.t_read_s)
            self._start(entry, t)
        self.now_s = max(self.now_s, now)

    def _start(self, entry: _Entry, t: float) -> None:
        self.now_s = t
        if entry.error is not None:
            self._emit(entry, Status.ERROR, t, t, entry.error)
            return
        assert entry.spec is not None
        try:
            result = entry.spec.func(self, entry.args)
        except RobotError as exc:
            self._emit(entry, Status.ERROR, t, t, (exc.code, exc.message))
            return
        except Exception as exc:  # a user skill's bug must not take the server down
            self._emit(entry, Status.ERROR, t, t, (ErrorCode.SKILL_FAILED, f"{type(exc).__name__}: {exc}"))
            return
        if isinstance(result, Generator):
            self._running = _Running(entry, t, result, t)
            self._resume(self._running, t)
        else:
            self._finish(entry, t, t, result)

    def _resume(self, run: _Running, t: float) -> None:
        self.now_s = t
        try:
            wake = run.gen.send(None)
        except StopIteration as stop:
            self._running = None
            self._finish(run.entry, run.t_start_s, t, stop.value)
            return
        except RobotError as exc:
            self._running = None
            self._emit(run.entry, Status.ERROR, run.t_start_s, t, (exc.code, exc.message))
            return
        except Exception as exc:
            self._running = None
            self._emit(run.entry, Status.ERROR, run.t_start_s, t,
                       (ErrorCode.SKILL_FAILED, f"{type(exc).__name__}: {exc}"))
            return
        run.wake_s = float(wake)

    def _finish(self, entry: _Entry, t_start: float, t_done: float, result: Any) -> None:
        extra = result.extra if isinstance(result, SkillResult) else ()
        self._emit(entry, Status.DONE, t_start, t_done, extra=extra)

    def _run_immediate(self, entry: _Entry, now: float) -> None:
        assert entry.spec is not None
        try:
            result = entry.spec.func(self, entry.args)
        except RobotError as exc:
            self._emit(entry, Status.ERROR, now, now, (exc.code, exc.message))
            return
        except Exception as exc:  # as in _start: a user skill's bug is its error ack, not the server's death
            self._emit(entry, Status.ERROR, now, now, (ErrorCode.SKILL_FAILED, f"{type(exc).__name__}: {exc}"))
            return
        if isinstance(result, Generator):
            result.close()
            self._emit(entry, Status.ERROR, now, now, (ErrorCode.INTERNAL, "immediate skill must not wait"))
            return
        self._finish(entry, now, now, result)

    def _stop(self, entry: _Entry, now: float) -> None:
        run = self._running
        if run is not None and run.entry.spec is not _STOP_RUN:
            run.gen.close()
            self._running = None
            self._emit(run.entry, Status.ABORTED, run.t_start_s, now)
        # Everything queued is aborted except earlier stops: a stop never aborts another stop. After a stop the
        # queue holds only stops, each waiting for the arm to be at rest, so each is answered done then, in order.
        stops = deque(e for e in self._queue if e.spec is _STOP_RUN)
        for e in self._queue:
            if e.spec is not _STOP_RUN:
                self._emit(e, Status.ABORTED, now, now)
        self._queue = stops
        self._queued_by_conn.clear()
        for e in stops:
            self._queued_by_conn[e.conn] = self._queued_by_conn.get(e.conn, 0) + 1
        self.pending_speed_pct = self.io.pending_hand = None  # nor does a deferred OPEN/CLOSE act after a stop
        self.trajectory.stop(now)
        stop_entry = _Entry(entry.conn, entry.id, now, _STOP_RUN)
        if self._running is None and not stops:
            self._start(stop_entry, now)
        else:
            # A stop is already bringing the arm to rest: this one is answered when it has.
            self._enqueue(stop_entry)

    # -- output --------------------------------------------------------------------------------------------
    def _emit(self, entry: _Entry, status: Status, t_start: float, t_done: float,
              error: tuple[int, str | None] | None = None, extra: tuple[str, ...] = ()) -> None:
        if status is not Status.ABORTED:
            self.executed += 1
        if status is Status.ERROR and entry.error is None and error is not None:
            # a skill that ran and failed (not a line that did not parse): what the status skill reports
            self.last_error = (int(error[0]), error[1] or "")
        if entry.tracked:  # answered: its ID is free again on its connection
            entry.tracked = False
            ids = self._inflight.get(entry.conn)
            if ids is not None:
                n = ids.get(entry.id, 1) - 1
                if n > 0:
                    ids[entry.id] = n
                else:
                    ids.pop(entry.id, None)
                    if not ids:
                        del self._inflight[entry.conn]
        if entry.conn not in self._conns:
            return
        pose = self.here_at(t_done)
        if status is Status.ERROR:
            assert error is not None
            ack = Ack.error(entry.id, int(error[0]), error[1], t_start, t_done, pose)
        else:
            ack = Ack(entry.id, status, t_start, t_done, pose, extra)
        self._out.append(Outgoing(entry.conn, ack))

    def _drain(self) -> list[Outgoing]:
        out, self._out = self._out, []
        return out

    # -- the robot, as skills see it ------------------------------------------------------------------------
    def joints_at(self, t_s: float) -> tuple[float, ...]:
        return self.trajectory.position(t_s)

    def here_at(self, t_s: float) -> Pose:
        """V+ ``HERE`` at ``t_s``: the tool pose in the world frame."""
        return self._forward(self.trajectory.position(t_s))

    def _forward(self, joints: tuple[float, ...]) -> Pose:
        # At rest every ack asks for the same pose: remember the last one.
        cache = self._fk_cache
        if cache is not None and cache[0] == joints and cache[1] == self.tool:
            return cache[2]
        pose = self.model.forward(joints, self.tool)
        self._fk_cache = (joints, self.tool, pose)
        return pose

    @property
    def joints_deg(self) -> tuple[float, ...]:
        return self.joints_at(self.now_s)

    @property
    def here(self) -> Pose:
        return self.here_at(self.now_s)

    @property
    def air(self) -> bool:
        return self.signals.get(AIR_SIGNAL, False)

    def state(self, t_s: float) -> ControllerState:
        """Snapshot for the state stream at ``t_s`` (may be later than the last processed event)."""
        joints = self.trajectory.position(t_s)
        speed = self.trajectory.current_speed_pct(t_s)
        if speed is None:
            speed = (self.pending_speed_pct or self.always_speed_pct) * self.monitor_speed_pct / 100.0
        return ControllerState(t_s, joints, self._forward(joints), self.trajectory.in_motion(t_s),
                               float(speed), self.air, self.io.snapshot(t_s))

    # -- the world (aioadept.world) ------------------------------------------------------------------------
    def _hand_drive(self, drive: HandState, t_s: float) -> None:
        """The valves drive the hand another way at ``t_s``: the world grasps or releases a part at the TCP."""
        assert self.world is not None
        tool = self.here_at(t_s)
        if drive is HandState.CLOSED:
            events = self.world.hand_closed(t_s, tool)
        else:
            events = self.world.hand_opened(t_s, tool)
        self.io.hand.part = self.world.held is not None
        self._apply_world_events(events, t_s)

    def _world_step(self, t_s: float) -> None:
        """The I/O advanced to ``t_s``: the feeder's queue may bring the next part (its sensor is an input)."""
        assert self.world is not None
        if self.world.queued:
            self._apply_world_events(self.world.step(t_s, self.here_at(t_s)), t_s)

    def _apply_world_events(self, events: Sequence[WorldEvent], t_s: float) -> None:
        for ev in events:
            if ev.kind == "sensor":
                self.io.set_input(ev.signal, ev.on, t_s)
            elif ev.error:  # a part fell: an error in the sim's log (and in the world stream), never silent
                log.error("world: %s (t=%.3f s)", ev.text, ev.t_s)
            else:
                log.info("world: %s part %d (t=%.3f s)", ev.kind, ev.part, ev.t_s)

    def world_snapshot(self, t_s: float) -> WorldSnapshot | None:
        """The world at ``t_s`` (a held part follows the tool there), or None without a world."""
        if self.world is None:
            return None
        return self.world.snapshot(t_s, self.here_at(t_s))

    def take_speed_pct(self) -> float:
        """The effective speed (program x monitor, at most ``max_speed_pct``) for the next motion; consumes a
        one-shot ``set_speed``."""
        program = self.always_speed_pct if self.pending_speed_pct is None else self.pending_speed_pct
        self.pending_speed_pct = None
        return min(program * self.monitor_speed_pct / 100.0, self.max_speed_pct)

    def request_config(self, *, shoulder: int = 0, elbow: int = 0, wrist: int = 0, single: bool | None = None) -> None:
        """V+ ``RIGHTY``/``LEFTY`` (shoulder +1/-1), ``ABOVE``/``BELOW`` (elbow +1/-1), ``NOFLIP``/``FLIP`` (wrist
        +1/-1), ``SINGLE``/``MULTIPLE`` (single True/False): the next motion to a pose ends in that configuration
        (:class:`aioadept.robots.base.ConfigRequest`). Requests add up until a motion takes them. The Python
        sim's skills do not call it (the wire protocol has no configuration skill); the model and V+ do."""
        r = self.config_request or ConfigRequest()
        self.config_request = ConfigRequest(shoulder or r.shoulder, elbow or r.elbow, wrist or r.wrist,
                                                r.single if single is None else single)

    def take_config(self) -> ConfigRequest | None:
        """The configuration request for this motion, consumed (as the one-shot speed)."""
        r, self.config_request = self.config_request, None
        return r

    def set_duration(self, seconds: float, *, always: bool = False) -> None:
        """V+ ``DURATION s [ALWAYS]``: the next (every) motion takes at least ``s`` seconds at 100 % monitor speed
        (slower monitor speed stretches it as every motion time); 0 turns it off. Raises ``ValueError`` for a
        negative or non-finite time."""
        if not (math.isfinite(seconds) and seconds >= 0):
            raise ValueError(f"DURATION {seconds!r}: expected a time >= 0 s")
        if always:
            self.always_duration_s, self.pending_duration_s = float(seconds), None
        else:
            self.pending_duration_s = float(seconds)

    def take_duration_s(self) -> float:
        """The least duration (robot time) of this motion, consuming a one-shot DURATION."""
        d = self.always_duration_s if self.pending_duration_s is None else self.pending_duration_s
        self.pending_duration_s = None
        return d * 100.0 / self.monitor_speed_pct

    def move_joints(self, target_deg: Sequence[float]) -> SkillGen:
        """Generator for skills: check the path, wait for a motion slot, start the motion (V+ ``MOVE``)."""
        speed = self.take_speed_pct()
        least = self.take_duration_s()
        target = self._model_joints(target_deg)
        start = self.trajectory.end_deg
        # Both ends inside the limit box: the joint-space segment between them is too (the box is convex).
        self.model.check_joint_path(start, target, limits=self.joint_limits)
        # Forward processing is one motion deep: the instruction waits until the motion executing now begins to
        # decelerate (where this one blends in), so its ack says the motion has started.
        while True:
            ready = self.trajectory.ready_s()
            if ready is None or ready <= self.now_s:
                break
            yield ready
        self.trajectory.add(target, self.now_s, speed_pct=speed, accel_pct=self.accel_pct, min_duration_s=least)
        self.io.motion_started(self.now_s)  # a deferred OPEN/CLOSE/RELAX acts as the motion starts
        return None

    def _model_joints(self, values: Sequence[float]) -> tuple[float, ...]:
        """The joint values of a joint motion: the wire's six values carry a four-axis arm's joints first and
        zeros after them (a value there would move nothing, so it is refused rather than ignored)."""
        try:
            return model_joints(self.model.name, self.model.dof, values)
        except ValueError as exc:
            raise RobotError(ErrorCode.ILLEGAL_VALUE, str(exc)) from None

    def move_pose(self, pose: Pose) -> SkillGen:
        """Generator for skills: inverse kinematics from the planned end, then :meth:`move_joints`."""
        try:
            target = self.model.inverse(pose, self.trajectory.end_deg, self.tool, limits=self.joint_limits,
                                 jump=self.jump_limit, config=self.take_config())
        except RobotError:
            self.take_speed_pct()  # the failed motion instruction still consumes SPEED (and DURATION)
            self.take_duration_s()
            raise
        return (yield from self.move_joints(target))

    # -- straight-line motion (V+ MOVES, APPROS, DEPARTS) ---------------------------------------------
    def planned_end_pose(self) -> Pose:
        """The tool pose where the planned motions end: where the next motion starts (V+ APPRO/DEPART use it)."""
        return self._forward(self.trajectory.end_deg)

    def plan_line(self, pose: Pose) -> LinePath:
        """The straight line from where the planned motions end to ``pose``, checked along its whole length
        (:func:`aioadept.sim.line.plan_tool_line`); raises ``RobotError`` before anything moves."""
        return plan_tool_line(self.trajectory.end_deg, pose, self.tool, joint_limits=self.joint_limits,
                              jump=self.jump_limit, model=self.model)

    def move_line(self, pose: Pose) -> SkillGen:
        """Generator for skills: V+ ``MOVES``. Consume the one-shot speed, check the whole line (refused before
        anything moves), wait for a motion slot as :meth:`move_joints`, start the line."""
        speed = self.take_speed_pct()  # a refused motion instruction consumes SPEED too
        least = self.take_duration_s()
        config = self.take_config()
        if config is not None and config.changes(self.trajectory.end_deg, self.model):
            # V+ changes configuration only in a joint-interpolated motion; a line cannot (UNCONFIRMED code)
            raise RobotError(ErrorCode.OUT_OF_REACH, "configuration change asked for a straight-line motion")
        path = self.plan_line(pose)
        while True:
            ready = self.trajectory.ready_s()
            if ready is None or ready <= self.now_s:
                break
            yield ready
        self.trajectory.add_line(path, self.now_s, speed_pct=speed, accel_pct=self.accel_pct, min_duration_s=least)
        self.io.motion_started(self.now_s)  # a deferred OPEN/CLOSE/RELAX acts as the motion starts, as for MOVE
        return None

    def wait_rest(self) -> SkillGen:
        """Generator for skills: V+ ``BREAK``, until every planned motion is done."""
        while self.trajectory.t_rest_s > self.now_s:
            yield self.trajectory.t_rest_s
        return None


__all__ = ["Controller", "ControllerState", "Outgoing"]
