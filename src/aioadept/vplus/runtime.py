"""The V+ run time: global data, tasks and their scheduler, the clock, built-in functions and instructions.

Programs compiled by :mod:`aioadept.vplus.compiler` run here as generators, one stack of them per task.

**Time slicing.** V+ divides time into slices and runs the tasks by priority in each slice; a task gives up the
rest of its slice when it waits (WAIT, READ, a motion). The emulator runs the ready tasks round-robin in task-number
order. In virtual time a task runs until it blocks or has run ``BUDGET`` loop iterations (counted at loop back-edges
and GOTOs), which ends its slice, and each ended slice costs ``slice_s`` (1 ms) of virtual time, so a busy-wait
loop on ``TIMER`` terminates; when every task is blocked the clock jumps to the earliest wake-up. In real time the
clock is the wall clock, a slice ends when the task has run ``SLICE_S`` (V+'s 1 ms slice: V+ Language User's
Guide, "Scheduling of Program Execution Tasks", pp. 48-50: at each 1 ms interval the scheduler looks for another
task to run, and tasks of equal priority take turns), looked at every ``REAL_BUDGET`` loop iterations and at each
CALL, and the scheduler returns to asyncio between rounds so that sockets are served. (A slice of 2000 iterations
let a reader busy with one client's flood run 45 ms at a stretch: the executor, and a stop's ack, waited that
long for each turn.)

``WAIT`` without a condition waits for the next trajectory cycle (``cycle_s``); ``WAIT cond`` re-tests the
condition once per cycle. A task blocked in ``READ`` mode 0 is also woken as soon as data arrives.
"""

from __future__ import annotations

import math
import re
import sys
import time
from collections import deque
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import Any

from aioadept.vplus import builtins as B
from aioadept.vplus import errors as E
from aioadept.vplus import iodev
from aioadept.vplus import nodes
from aioadept.vplus.compiler import BUDGET, compile_program
from aioadept.vplus.errors import VPlusError, VPlusHalt
from aioadept.vplus.loader import LoadProblem, Module
from aioadept.vplus.trace import Every, Frame, stack
from aioadept.vplus.values import _FB, _GOTO, MAX_STRING, _Goto, _LocArray, _Missing, f32  # noqa: F401 (re-exported)

PREEMPT = -1.0
SLICE_S = 0.001
"""Real time: how long a task runs before the others get their turn (V+'s time slice, module docstring)."""
REAL_BUDGET = 16
"""Real time: loop iterations between two looks at the clock (a look costs about as much as 2 iterations)."""
STORAGE_LIMIT = 262_144
"""Array elements all programs may hold at once (``Runtime(storage_limit=...)``, ``Emulator(storage_limit=...)``):
the emulator's program memory. Arrays are what a program can grow without end (names are fixed by the program text
and a string holds at most 128 characters), so a skill that fills an array without end gets V+'s
``*Not enough storage area*`` instead of growing the process (by about 60 MB at this limit)."""
CONSOLE_LINES = 10_000
"""Console lines kept for :attr:`Emulator.console` (a program that TYPEs without end keeps the last ones)."""

_UNBOUND_RE = re.compile(r"(?:variable|name) '(V_\w+)'")   # unbound local, or a local never assigned

_COMPILED: dict[tuple, tuple] = {}
"""Code objects of compiled programs by their source text (and the DOUBLE names, which change the code): an
emulator built again from the same files (one per test) only runs the code in a fresh namespace. The code and
its constants are immutable; each runtime has its own namespace and data."""


# -- clocks ------------------------------------------------------------------------------------------------------

class VirtualClock:
    """Deterministic time: it moves only when the scheduler advances it (tests run as fast as possible)."""

    virtual = True

    def __init__(self, start_s: float = 0.0) -> None:
        self.now = start_s


class RealClock:
    """Wall-clock seconds since the emulator started (``time.monotonic``)."""

    virtual = False

    def __init__(self) -> None:
        import time

        self._mono = time.monotonic
        self._t0 = time.monotonic()

    @property
    def now(self) -> float:
        return self._mono() - self._t0


# -- tasks -------------------------------------------------------------------------------------------------------

@dataclass(eq=False)
class Task:
    """One V+ program task: its generator stack, wake-up time and per-task state (LUNs, REACTE, errors)."""

    num: int
    program: str
    gen: Generator | None = None
    wake: float = 0.0
    io_wait: bool = False
    state: str = "idle"                # idle, running, done, error, aborted, paused
    error: VPlusError | None = None
    reacte: str | None = None
    in_reaction: bool = False
    last_error: int = 0
    luns: dict[int, Any] = field(default_factory=dict)
    iostat: dict[int, int] = field(default_factory=dict)
    statics: dict[str, dict] = field(default_factory=dict)
    robot_attached: bool = False
    cycles: int = 1
    stop_cycle: bool = False
    paused: bool = False
    events: int = 0
    cond_wait: bool = False            # blocked in WAIT cond: re-tested when another task made progress
    event_wait: bool = False           # blocked in WAIT.EVENT with the event mask: woken by SET.EVENT / its I/O
    motion_wait: bool = False          # blocked in a motion instruction: woken by a BRAKE
    halted_at: tuple[str | None, str, int] | None = None   # HALT or PAUSE: (file, program, line)
    trapped: tuple[str, VPlusError] | None = None  # (REACTE program, error) of the last error it trapped
    throw: VPlusError | None = None    # raised in the task where it yielded, when it next runs (storage full)
    trace: bool = False                # a tracer's line hook runs at every statement (stepping: aioadept.vplus.trace)
    held: bool = False                 # a tracer holds the task at a line or an error until Runtime.release
    frames: list[Frame] | None = None  # while held: its V+ call stack, innermost first


class Runtime:
    """Global data, compiled programs and tasks. Built by :class:`aioadept.vplus.Emulator`."""

    on_new: list[Callable[[Runtime], None]] = []
    """Called with every runtime made from now on in this process, its programs compiled and no task started: where
    a tool attaches a tracer (``set_tracer``) to each (V+ line coverage, aioadept.vplus.coverage_plugin)."""

    def __init__(self, module: Module, *, clock: Any = None, cycle_s: float = 0.016, slice_s: float = 0.001,
                 console: Callable[[int, str], None] | None = None, robot: Any = None,
                 storage_limit: int = STORAGE_LIMIT) -> None:
        self.module = module
        self.clock = clock or VirtualClock()
        self.cycle_s = cycle_s
        self.slice_s = slice_s
        self.globals: dict[str, Any] = {}
        self.programs: dict[str, Callable] = {}
        self.problems: list[LoadProblem] = list(module.problems)
        self.not_executable: dict[str, list[LoadProblem]] = {}
        self.tasks: dict[int, Task] = {}
        self._order: list[Task] = []       # self.tasks by task number (the round-robin order), kept by _set_task
        from aioadept.sim.io import DigitalIO

        self.io = DigitalIO()
        """Digital I/O and the hand; the emulator gives it the robot's (``controller.io``), the one model."""
        self.signals: dict[int, bool] = self.io.values
        self.timers: dict[int, float] = {}
        self.t0 = self.clock.now
        self.console_lines: deque[tuple[int, str]] = deque(maxlen=CONSOLE_LINES)
        self._console = console
        self.robot = robot
        self.switches: dict[str, bool] = {"DRY.RUN": False}
        self.devices: Any = None           # the TCP device layer (aioadept.vplus.tcp.Network)
        self.input: deque[str] = deque()
        self.on_wake: Callable[[], None] | None = None   # real time: poke the scheduler loop
        self.on_task_end: Callable[[Task], None] | None = None
        """Called when a task stops running (done, error, aborted), before its robot and LUNs are released:
        ``aioadept sim --vplus`` decides there whether the server has died (aioadept.vplus.cli)."""
        self.on_task_pause: Callable[[Task], None] | None = None
        """Called when a task executes PAUSE (only PROCEED resumes it: ``Emulator.proceed``, no one in the CLI)."""
        self.realtime = not self.clock.virtual
        # a RealClock's start: ``now`` reads the monotonic clock itself (it is read ~20 times per here round trip)
        self._mono_t0: float | None = self.clock._t0 if type(self.clock) is RealClock else None
        self.slice_end = math.inf          # real time: when the running task's slice ends (time.monotonic)
        self.storage_limit = storage_limit
        self._storage_at = 0.0             # when storage is next counted (once per cycle: it costs ~20 us)
        self.tracer: Any = None            # set_tracer (aioadept.vplus.trace)
        self._trace_lines: dict[str, Any] = {}
        self._load_data()
        self.compile_all()
        for hook in Runtime.on_new:
            hook(self)

    # -- loading ------------------------------------------------------------------------------------------
    def _load_data(self) -> None:
        from aioadept.vplus import locations as loc

        for kind, name, index, value in self.module.data:
            if kind == "LOC":
                # six: x y z yaw pitch roll; twelve: the 3x4 matrix row by row (the loader reorders STORE's)
                v = loc.trans(*value) if len(value) == 6 else loc.Transform(tuple(float(x) for x in value))
            elif kind == "PPOINT":
                v = loc.ppoint(*value)
            elif kind == "REAL":
                v = f32(value)
            else:
                v = value
            if index is None:
                self.globals[name] = v
            else:
                arr = self.globals.get(name + "[]")
                if arr is None:
                    arr = self.globals[name + "[]"] = _LocArray() if kind == "LOC" else {}
                    if kind == "LOC":
                        arr.name = name
                arr[index] = v

    def doubles(self) -> set[str]:
        out = {name for kind, name, _, _ in self.module.data if kind == "DOUBLE"}
        for prog in self.module.programs.values():
            for _, st in prog.steps:
                if isinstance(st, nodes.Declare) and st.word == "GLOBAL":
                    out |= {n for n, t, _ in st.names if t == "DOUBLE"}
        return out

    def compile_all(self, traced: bool = False, variables: bool = True) -> None:
        """Compile every program (``traced``: the instrumented form, aioadept.vplus.trace; ``variables``: with its
        AUTOs where a tracer reads them) into ``programs``, which is updated in place (the generated code's CALL
        holds it)."""
        ns_base = self._namespace()
        doubles = self.doubles()
        for name, prog in self.module.programs.items():
            if not prog.executable:
                self.not_executable[name] = prog.problems
                continue
            key = (prog.file, prog.name, prog.line, repr(prog.params), repr(sorted(prog.source.items())),
                   frozenset(doubles), traced, variables)
            hit = _COMPILED.get(key)
            if hit is None:
                src, consts, problems = compile_program(prog, doubles, traced=traced, variables=variables)
                try:
                    code = None if problems else compile(src, f"<V+ {prog.name} ({prog.file})>", "exec")
                except SyntaxError as exc:
                    # Python's limit of 20 nested blocks: each V+ loop is one or two, a loop whose body holds
                    # labels four (compiler module doc); a program nested deeper does not run, and says why
                    code, problems = None, [LoadProblem(
                        prog.file, prog.line, f"blocks nested too deep for the emulator (Python: {exc.msg})",
                        prog.name, prog.name)]
                if len(_COMPILED) >= 4096:
                    _COMPILED.clear()
                hit = _COMPILED[key] = (code, consts, problems)
            code, consts, problems = hit
            if problems:
                if not traced:        # the plain form was compiled first and has reported them
                    self.not_executable[name] = problems
                    self.problems.extend(problems)
                continue
            ns = dict(ns_base)
            ns["_K"] = consts
            if traced:
                ns["_PROG"] = prog
                ns["_BP"] = self._trace_lines.setdefault(name, set())
            exec(code, ns)
            self.programs[name] = ns["_prog"]

    # -- tracing (aioadept.vplus.trace) ---------------------------------------------------------------------
    def set_tracer(self, tracer: Any, *, all_lines: bool = False, variables: bool = True) -> None:
        """Run the programs in their instrumented form, calling ``tracer`` (aioadept.vplus.trace); before any task
        starts. ``all_lines``: its line hook runs before every statement. ``variables=False``: the tracer reads no
        AUTO variable (``Frame.autos`` is empty), which keeps them as fast as without a tracer (line coverage)."""
        if self.active():
            raise RuntimeError("set_tracer: a task is running; set the tracer before tasks start")
        self.tracer = tracer
        if all_lines:
            self._trace_lines = {name: Every() for name in self.module.programs}
        self.compile_all(traced=True, variables=variables)

    def trace_lines(self, program: str) -> set[int]:
        """The lines of ``program`` at which the tracer's line hook runs for every task (breakpoints)."""
        return self._trace_lines.setdefault(program, set())

    def release(self, T: Task) -> None:
        """Let a task held by the tracer go on."""
        T.held = False
        if T.state == "running":
            T.wake = self.now
            self._poke()

    def _line_hook(self, T: Task, line: int) -> Generator:
        """``_dbg`` of the instrumented code: the tracer's line hook, and the wait while it holds the task."""
        tracer = self.tracer
        if tracer is not None:
            f = sys._getframe(1)             # the program that runs the hook
            prog = f.f_globals["_PROG"]
            tracer.line(T, Frame(prog.name, prog.file, line, prog, f))
            if T.held:
                T.frames = stack(f, line)
                yield from self._hold(T)

    def _hold(self, T: Task) -> Generator:
        try:
            while T.held:
                T.wake = self.next_tick()
                yield T.wake
        finally:
            T.frames = None

    # -- console ------------------------------------------------------------------------------------------
    def console(self, task: int, text: str) -> None:
        self.console_lines.append((task, text))
        if self._console is not None:
            self._console(task, text)

    @property
    def now(self) -> float:
        t0 = self._mono_t0
        return _mono() - t0 if t0 is not None else self.clock.now

    # -- tasks --------------------------------------------------------------------------------------------
    def start_task(self, num: int, program: str, args: tuple = (), *, cycles: int = 1) -> Task:
        """EXECUTE: start ``program`` in task ``num`` (which must be idle)."""
        old = self.tasks.get(num)
        if old is not None and old.state in ("running", "paused"):
            raise VPlusError(E.ILLEGAL_OPERATION, f"*Task {num} already active*")
        if old is not None:
            self._release(old)
        t = Task(num, program, wake=self.now, cycles=cycles)
        t.state = "running"
        t.gen = self._task_main(t, program, args)
        self._set_task(num, t)
        self._poke()
        return t

    def _task_main(self, T: Task, program: str, args: tuple) -> Generator:
        n = 0
        while True:
            yield from self.call(T, program, args)
            n += 1
            if T.stop_cycle or (T.cycles >= 0 and n >= T.cycles):
                return

    def call(self, T: Task, name: str, args: tuple) -> Generator:
        f = self.programs.get(name)
        if f is None:
            if name in self.not_executable:
                p = self.not_executable[name][0]
                raise VPlusError(E.NOT_EXECUTABLE, f"*Program not executable* {name}: {p}")
            raise VPlusError(E.UNDEFINED_PROGRAM, f"{E.text(E.UNDEFINED_PROGRAM)} {name}")
        return f(T, args)

    def _release(self, T: Task) -> None:
        iodev.release_task(self, T)
        if T.robot_attached and self.robot is not None:
            T.robot_attached = False
            self.robot.detach(T.num)

    def _end_task(self, T: Task, state: str, err: VPlusError | None = None, *, brake: bool = False) -> None:
        """The task stops running. ``brake`` (an error, HALT, ABORT): the motion of the robot it has attached is
        braked: no motion goes on that no program commands any more (docs/vplus.md, "When a task stops")."""
        T.state = state
        T.error = err
        if brake and T.robot_attached and self.robot is not None:
            self.robot.brake(self.now)
        if T.gen is not None:
            gen, T.gen = T.gen, None
            try:
                gen.close()
            except BaseException:  # noqa: BLE001 - a program's cleanup must not take the scheduler down
                pass
        if self.on_task_end is not None:
            self.on_task_end(T)
        self._release(T)

    def abort(self, num: int) -> None:
        """ABORT: stop the program of task ``num`` (its robot motion is braked)."""
        T = self.tasks.get(num)
        if T is None or T.state not in ("running", "paused"):
            return
        self.console(num, f"(task {num}) aborted")
        self._end_task(T, "aborted", brake=True)      # V+ ABORT stops the task's robot motion

    def kill(self, num: int) -> None:
        self.abort(num)
        self._set_task(num, None)

    def _set_task(self, num: int, t: Task | None) -> None:
        if t is None:
            self.tasks.pop(num, None)
        else:
            self.tasks[num] = t
        self._order = [self.tasks[n] for n in sorted(self.tasks)]

    def ready_tasks(self) -> list[Task]:
        now = self.now
        return [t for t in self._order if t.state == "running" and t.wake <= now]

    def any_ready(self) -> bool:
        now = self.now
        for t in self._order:
            if t.wake <= now and t.state == "running":
                return True
        return False

    def next_wake(self) -> float | None:
        ws = [t.wake for t in self._order if t.state == "running"]
        return min(ws) if ws else None

    def active(self) -> bool:
        return any(t.state == "running" for t in self.tasks.values())

    def run_round(self) -> int:
        """Resume every ready task once; return how many slices ended by preemption.

        A task blocked in ``WAIT cond`` whose re-test failed made no progress; any other resumption may have
        changed globals or signals, so after it every task in ``WAIT cond`` is re-tested in the next round (V+:
        a false WAIT condition releases the CPU to any task and is tested again when the task is next scheduled).
        """
        preempted = 0
        progress = False
        now = self.now
        # A task woken by an earlier one in this round (SET.EVENT, a queued ack) runs in its turn of the same
        # round rather than one round later: the order stays by task number, and a woken reader's ack does not
        # wait for every other task's next turn. Every task still runs at most once per round.
        stale = False                     # a task ran since ``now`` was read: it may have woken a later one
        for T in self._order:
            if T.state != "running" or T.gen is None:
                continue
            if T.wake > now:
                if not stale:
                    continue
                now, stale = self.now, False
                if T.wake > now:
                    continue
            stale = True
            T.io_wait = False
            retest = T.cond_wait
            T.cond_wait = T.event_wait = T.motion_wait = False
            if not retest:
                progress = True
            counted = -1
            if now >= self._storage_at:
                self._storage_at = now + self.cycle_s
                counted = self.storage_used()
            if self.realtime:
                self.slice_end = _mono() + SLICE_S
            try:
                if T.throw is None:
                    w = T.gen.send(None)
                else:
                    err, T.throw = T.throw, None
                    w = T.gen.throw(err)
            except (Exception, VPlusHalt) as exc:
                T.gen = None
                self._stopped(T, exc)
                continue
            if w < 0:
                preempted += 1
                T.wake = self.now
            else:
                T.wake = w
            if counted >= 0:
                self._check_storage(T, counted)
            if retest and not T.cond_wait:
                progress = True           # the condition became true: the task went on
        if progress:
            self.wake_conditions()
        return preempted

    def _stopped(self, T: Task, exc: BaseException) -> None:
        """End task ``T``, whose program raised ``exc`` when resumed: StopIteration (it returned), HALT (with where
        it halted), a V+ error, or a Python exception (an emulator bug stops the task, not the emulator)."""
        if isinstance(exc, StopIteration):
            self._end_task(T, "done")
        elif isinstance(exc, VPlusHalt):
            if exc.program is not None:
                prog = self.module.programs.get(exc.program)
                T.halted_at = (prog.file if prog is not None else None, exc.program, exc.line or 0)
            if str(exc):
                self.console(T.num, str(exc))
            self._end_task(T, "done", brake=exc.brakes)
        elif isinstance(exc, VPlusError):
            self.console(T.num, f"{exc} (task {T.num})")
            self._end_task(T, "error", exc, brake=True)
        else:
            err = VPlusError(E.INTERNAL, f"*Emulator internal error* {type(exc).__name__}: {exc}")
            self.console(T.num, f"{err} (task {T.num})")
            self._end_task(T, "error", err, brake=True)

    def storage_used(self) -> int:
        """Array elements held now: global arrays, each task's LOCAL arrays and the AUTO arrays of its calls."""
        # (counted once per cycle while a server serves: plain loops, and a frame's locals read only for the
        # generators of compiled programs, not for built-ins such as READ or WAIT.EVENT that they yield from)
        n = 0
        for v in self.globals.values():
            if isinstance(v, dict):
                n += len(v)
        for T in self._order:
            for local in T.statics.values():
                for v in local.values():
                    if isinstance(v, dict):
                        n += len(v)
            gen = T.gen
            while gen is not None and gen.gi_frame is not None:
                if gen.gi_code.co_name == "_prog":
                    autos = gen.gi_frame.f_locals.get("L")       # a program's AUTO variables (compiler)
                    if type(autos) is dict:
                        for v in autos.values():
                            if isinstance(v, dict):
                                n += len(v)
                gen = gen.gi_yieldfrom
        return n

    def _check_storage(self, T: Task, before: int) -> None:
        """Once per cycle, around one task's turn: if the arrays hold more than ``storage_limit`` elements and
        grew during that turn, the task gets ``*Not enough storage area*`` where it yielded (in a real V+ the
        instruction that finds memory full fails; here the task that grows them fails within a few cycles of
        passing the limit). Memory stays full until arrays are freed, as on a controller."""
        used = self.storage_used()
        if used > self.storage_limit and used > before and T.state == "running" and T.gen is not None:
            T.throw = VPlusError(E.NO_STORAGE, f"{E.text(E.NO_STORAGE)} ({used} array elements, the emulator's "
                                               f"limit is {self.storage_limit})")
            T.wake = self.now

    def wake_conditions(self) -> None:
        """Something may have changed a WAIT condition: re-test every waiting condition in the next round."""
        now = self.now
        for T in self.tasks.values():
            if T.cond_wait and T.state == "running" and T.wake > now:
                T.wake = now

    def cond_tick(self, T: Task) -> float:
        """``WAIT cond`` is false: block until another task makes progress, an I/O event, or the next cycle."""
        T.cond_wait = True
        return self.next_tick()

    def signal_event(self, T: Task) -> None:
        """Set the event flag of task ``T`` (SET.EVENT, or I/O on its LUNs) and wake it if it waits for it."""
        T.events = 1
        if T.event_wait and T.state == "running" and T.wake > self.now:
            T.wake = self.now
            self._poke()

    def wake_motion_waiters(self) -> None:
        """A BRAKE: tasks blocked in a motion instruction look at the robot again at once."""
        now = self.now
        for T in self.tasks.values():
            if T.motion_wait and T.state == "running" and T.wake > now:
                T.wake = now

    def run_virtual(self, until: Callable[[], bool] | None = None, *, max_time_s: float | None = None,
                    max_rounds: int = 50_000_000) -> None:
        """Run in virtual time until ``until()`` is true, no task is active, or ``max_time_s`` is reached."""
        clock = self.clock
        assert clock.virtual, "run_virtual needs a VirtualClock"
        for _ in range(max_rounds):
            if until is not None and until():
                return
            if not self.active():
                return
            if self.ready_tasks():
                pre = self.run_round()
                if pre:
                    clock.now += self.slice_s * pre
            else:
                w = self.next_wake()
                if w is None:
                    return
                if max_time_s is not None and w > max_time_s:
                    clock.now = max(clock.now, max_time_s)
                    return
                clock.now = max(clock.now, w)
            if max_time_s is not None and clock.now >= max_time_s:
                return
        raise RuntimeError("run_virtual: round limit reached")

    def _poke(self) -> None:
        if self.on_wake is not None:
            self.on_wake()

    def wake_io(self, task: Task | None, woken: bool = False) -> None:
        """I/O arrived: a task blocked in READ mode 0 runs at once; conditions are re-tested.

        When the I/O woke ``task`` (``woken``: its READ or WAIT.EVENT), the conditions are re-tested after its turn
        instead (its turn is progress: run_round re-tests them in the next round of the same burst), when they can
        see what it did with the input: a re-test before it, which found nothing new, was a task resumption and
        a round trip's latency spent for nothing (the executor is task 1, the reader task 2)."""
        if task is not None and task.state == "running" and task.io_wait:
            task.wake = min(task.wake, self.now)
            woken = True
        if not woken:
            self.wake_conditions()
        self._poke()

    def io_event(self, task: Task) -> None:
        """An event (connect, data, close) on one of ``task``'s TCP LUNs: wake a READ, set its event flag."""
        woken = False
        if task.state == "running":
            task.events = 1
            if task.event_wait:
                task.wake = min(task.wake, self.now)
                woken = True
        self.wake_io(task, woken)

    def next_tick(self) -> float:
        c = self.cycle_s
        return (math.floor(self.now / c) + 1) * c

    # -- errors -------------------------------------------------------------------------------------------
    def on_error(self, T: Task, exc: BaseException, program: str, line: int) -> Generator:
        """An exception in a program step: make it a V+ error; REACTE handles it or it stops the task."""
        if isinstance(exc, VPlusError) and exc.fatal:
            raise exc
        err = self.as_vplus(exc)
        if err.program is None:
            err.program, err.line = program, line
            prog = self.module.programs.get(program)
            err.file = prog.file if prog is not None else None     # run-time errors name the file too
        err.task = T.num
        T.last_error = err.code
        if self.tracer is not None:
            frames = stack(sys._getframe(1), line)      # the program whose statement failed, and its callers
            self.tracer.error(T, err, frames)
            if T.held:
                T.frames = frames
                yield from self._hold(T)
        if T.reacte is not None and not T.in_reaction:
            handler, T.reacte = T.reacte, None      # V+: REACTE is disarmed when it triggers
            T.trapped = (handler, err)
            T.in_reaction = True
            try:
                yield from self.call(T, handler, ())
            finally:
                T.in_reaction = False
            return
        err.fatal = True
        raise err

    @staticmethod
    def as_vplus(exc: BaseException) -> VPlusError:
        if isinstance(exc, VPlusError):
            return exc
        from aioadept.errors import RobotError

        if isinstance(exc, RobotError):
            return VPlusError(int(exc.code), f"{E.text(int(exc.code))} {exc.message or ''}".strip())
        if isinstance(exc, KeyError):
            key = exc.args[0] if exc.args else "?"
            what = key if isinstance(key, str) else f"array element [{key}]"
            return VPlusError(E.UNDEFINED_VALUE, f"*Undefined value* {what}")
        if isinstance(exc, NameError):
            # an AUTO held as a Python local (compiler._local) read before any assignment
            m = _UNBOUND_RE.search(str(exc))
            if m:
                from aioadept.vplus.compiler import vplus_name

                return VPlusError(E.UNDEFINED_VALUE, f"*Undefined value* {vplus_name(m.group(1))}")
        if isinstance(exc, ZeroDivisionError):
            return VPlusError(E.DIVISION_BY_ZERO)
        if isinstance(exc, (TypeError, AttributeError)):
            return VPlusError(E.ILLEGAL_OPERATION, f"*Illegal operation* ({exc})")
        if isinstance(exc, (ValueError, OverflowError, IndexError)):
            return VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* ({exc})")
        return VPlusError(E.INTERNAL, f"*Emulator internal error* {type(exc).__name__}: {exc}")

    # -- the namespace of generated code ------------------------------------------------------------------
    def _namespace(self) -> dict[str, Any]:
        ns = B.namespace(self)
        ns["_dbg"] = self._line_hook
        # time slices (module docstring): the generated code counts loop iterations in _b from _BUDGET and then
        # asks _slice_over(); in real time a CALL ends the slice too once it has run SLICE_S
        if not self.realtime:
            ns["_BUDGET"] = BUDGET
            ns["_slice_over"] = _always
            return ns
        ns["_BUDGET"] = REAL_BUDGET
        ns["_slice_over"] = self.slice_over
        ns["_call"] = self._sliced_call()
        return ns

    def slice_over(self) -> bool:
        """Real time: the running task has used its slice (it yields PREEMPT; the others get their turn)."""
        return _mono() >= self.slice_end

    def _sliced_call(self) -> Callable[[Task, str, tuple], Generator]:
        """CALL (``_call`` of the generated code, as builtins' ``call``) that first ends the slice if it is over:
        straight-line code that calls programs, loop-free as it may be, is sliced too."""
        programs = self.programs           # filled by compile_all; never replaced

        def sliced_call(T: Task, name: str, args: tuple) -> Generator:
            f = programs.get(name)
            gen = self.call(T, name, args) if f is None else f(T, args)
            if _mono() >= self.slice_end:
                return _preempt_then(gen)
            return gen

        return sliced_call


def _always() -> bool:
    return True


def _preempt_then(gen: Generator) -> Generator:
    yield PREEMPT
    return (yield from gen)


_mono = time.monotonic
