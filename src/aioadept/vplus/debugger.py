"""The V+ debugger's core, without I/O: breakpoints, stepping, pausing, exception stops and inspection, per task.

A :class:`Debugger` is the emulator's tracer (:mod:`aioadept.vplus.trace`). It reports what happens through one
callback, ``on_event(name, body)``, with the Debug Adapter Protocol's event names and bodies (``stopped``,
``output``), so the DAP adapter (:mod:`aioadept.vplus.dap`) only moves messages. Tasks are the threads.

- Breakpoints by file and line (moved to the first statement at or after the line, in the program that holds
  it), with a V+ condition evaluated in the stopped frame, a hit count (``5``, ``>= 5``, ``% 5``) and a log
  message (``{expression}`` parts are V+ expressions): a logpoint prints instead of stopping.
- Step into, over and out; pause and continue one task or all. A stopped task waits; the other tasks run on (a
  breakpoint in the V+ server's executor leaves its reader serving ``stop``).
- A V+ error stops as an ``exception`` before REACTE takes it: ``all`` errors, ``untrapped`` (no REACTE armed,
  or in the REACTE program itself), or ``none``.
- Inspection: the call stack (program, file, line, arguments), the scopes AUTO, LOCAL and globals, arrays,
  strings, locations (x y z yaw pitch roll), precision points (joints); evaluate a V+ expression in a frame; set a
  variable (the new value is a V+ expression, stored as an assignment of that variable would store it).

**The arm while a task is stopped.** The manuals say a program stops at a breakpoint and waits for a step or a
resume (Adept DeskTop 4.3 online help, "Breakpoints"); what the robot does meanwhile they do not say
(UNCONFIRMED, docs/vplus.md "Debugging"). The safe side: when a task that has the robot attached stops, the arm is
braked (it comes to rest; the motion it was making is not resumed), and the debugger never starts a motion.
:meth:`Debugger.end` (the session ends) brakes the arm and aborts every task.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from aioadept.errors import AdeptError
from aioadept.vplus import nodes as N
from aioadept.vplus.compiler import _Gen
from aioadept.vplus.errors import VPlusError
from aioadept.vplus.locations import PrecisionPoint, Transform
from aioadept.vplus.parse import Parser, VSyntaxError, tokenize
from aioadept.vplus.program import Program
from aioadept.vplus.runtime import Runtime, Task
from aioadept.vplus.trace import Frame, is_program_frame, stack, suspended_stack

EXCEPTION_MODES = ("all", "untrapped", "none")


class DebugError(AdeptError):
    """A request the debugger cannot do (a bad expression, no such task or frame): its message is for the user."""


@dataclass(eq=False)
class Breakpoint:
    """One breakpoint: where it was asked for and where it is (``line``: the statement it stops before)."""

    id: int
    file: str
    requested: int
    line: int
    program: str | None
    condition: str | None = None
    hit_condition: str | None = None
    log_message: str | None = None
    hits: int = 0

    @property
    def verified(self) -> bool:
        return self.program is not None


@dataclass
class _Step:
    kind: str          # in, over, out
    depth: int         # the task's call depth where the step started


@dataclass
class Stop:
    """Why a task is stopped: ``reason`` as DAP's stopped event's, ``text`` (an error's message)."""

    reason: str
    text: str = ""
    breakpoints: list[int] = field(default_factory=list)


_HIT_RE = re.compile(r"\s*(>=|<=|==|>|<|%)?\s*(\d+)\s*\Z")


class Debugger:
    """The debugger of one runtime (attach before tasks start: it compiles the instrumented form)."""

    def __init__(self, rt: Runtime, on_event: Callable[[str, dict], None] = lambda name, body: None) -> None:
        self.rt = rt
        self.on_event = on_event
        self.exceptions = "untrapped"
        self.stopped: dict[int, Stop] = {}
        self._bps: dict[tuple[str, int], Breakpoint] = {}
        self._by_file: dict[str, list[Breakpoint]] = {}
        self._next_id = 1
        self._steps: dict[int, _Step] = {}
        self._pause: set[int] = set()
        self._entry: set[int] = set()
        # programs name their file as loaded (its base name); sources are the files' real paths
        self._paths = {os.path.basename(f): os.path.realpath(f) for f in rt.module.files}
        rt.set_tracer(self)

    def path_of(self, file: str) -> str:
        """The real path of a program's file (as its programs name it)."""
        return self._paths.get(file, file)

    # -- breakpoints ------------------------------------------------------------------------------------------
    def set_breakpoints(self, path: str, specs: list[dict]) -> list[Breakpoint]:
        """Replace the breakpoints of file ``path`` by ``specs`` (DAP SourceBreakpoint: line, condition,
        hitCondition, logMessage); each result says where it is, or that no statement is there."""
        key = _same_file(path)
        for bp in self._by_file.pop(key, []):
            if bp.program is not None:
                self._bps.pop((bp.program, bp.line), None)
                self.rt.trace_lines(bp.program).discard(bp.line)
        out: list[Breakpoint] = []
        for spec in specs:
            line = int(spec["line"])
            program, at = self._statement_at(key, line)
            bp = Breakpoint(self._next_id, path, line, at, program, spec.get("condition") or None,
                            spec.get("hitCondition") or None, spec.get("logMessage") or None)
            self._next_id += 1
            if bp.hit_condition is not None and not _HIT_RE.match(bp.hit_condition):
                raise DebugError(f"hit count {bp.hit_condition!r}: expected N, >= N, > N, == N or % N")
            if program is not None:
                self._bps[(program, at)] = bp
                self.rt.trace_lines(program).add(at)
            out.append(bp)
        self._by_file[key] = out
        return out

    def _statement_at(self, key: str, line: int) -> tuple[str | None, int]:
        """(program, line) of the first statement at or after ``line`` in the program of file ``key`` that holds
        it; (None, line) if none."""
        for name, prog in self.rt.module.programs.items():
            if _same_file(self.path_of(prog.file)) != key or not prog.source:
                continue
            if not prog.line <= line <= max(prog.source):
                continue
            lines = sorted(n for n in self.statement_lines(name) if n >= line)
            return (name, lines[0]) if lines else (None, line)
        return None, line

    def statement_lines(self, program: str) -> set[int]:
        """The lines of ``program`` a task can stop at (its statements, and IF/WHILE/CASE/FOR heads)."""
        f = self.rt.programs.get(program)
        if f is None:
            return set()
        return set(f.__globals__["_K"][-1]) - {0}

    # -- the tracer (aioadept.vplus.trace) -------------------------------------------------------------------
    def line(self, T: Task, frame: Frame) -> None:
        bp = self._bps.get((frame.program, frame.line))
        if bp is not None and self._breakpoint_hit(T, bp, frame):
            return
        num = T.num
        if num in self._entry:
            self._entry.discard(num)
            self._stop(T, Stop("entry"), frame)
        elif num in self._pause:
            self._pause.discard(num)
            self._stop(T, Stop("pause"), frame)
        else:
            step = self._steps.get(num)
            if step is not None:
                depth = _depth(frame)
                if step.kind == "in" or (step.kind == "over" and depth <= step.depth) or depth < step.depth:
                    self._stop(T, Stop("step"), frame)

    def _breakpoint_hit(self, T: Task, bp: Breakpoint, frame: Frame) -> bool:
        """Count a breakpoint reached; True if it stopped the task."""
        if bp.condition is not None:
            try:
                if not _true(self.evaluate(bp.condition, frame)):
                    return False
            except DebugError as exc:
                self._output(f"breakpoint condition {bp.condition!r} at {frame.file}:{bp.line}: {exc}\n")
                return False
        bp.hits += 1
        if bp.hit_condition is not None and not _hit_ok(bp.hits, bp.hit_condition):
            return False
        if bp.log_message is not None:
            self._output(self._interpolate(bp.log_message, frame) + "\n")
            return False
        self._stop(T, Stop("breakpoint", breakpoints=[bp.id]), frame)
        return True

    def error(self, T: Task, err: VPlusError, frames: list[Frame]) -> None:
        mode = self.exceptions
        untrapped = T.reacte is None or T.in_reaction
        if mode == "all" or (mode == "untrapped" and untrapped):
            self._stop(T, Stop("exception", str(err.message or err)), frames)

    def _stop(self, T: Task, why: Stop, where: Frame | list[Frame]) -> None:
        """Hold the task where it is (``where``: the frame of its line hook, or the stack of its error)."""
        T.frames = where if isinstance(where, list) else stack(where.pyframe, where.line)
        T.held = True
        T.trace = False
        self._steps.pop(T.num, None)
        self.stopped[T.num] = why
        robot = self.rt.robot
        if T.robot_attached and robot is not None:
            robot.brake(self.rt.now)          # the safe side (module docstring): the arm comes to rest
        body = {"reason": why.reason, "threadId": T.num, "allThreadsStopped": False}
        if why.text:
            body["text"] = why.text
            body["description"] = why.text
        if why.breakpoints:
            body["hitBreakpointIds"] = why.breakpoints
        self.on_event("stopped", body)

    def _output(self, text: str) -> None:
        self.on_event("output", {"category": "console", "output": text})

    def _interpolate(self, message: str, frame: Frame) -> str:
        def one(m: re.Match) -> str:
            try:
                return render(self.evaluate(m.group(1), frame))
            except DebugError as exc:
                return f"<{exc}>"

        return re.sub(r"\{([^{}]+)\}", one, message)

    # -- run control ------------------------------------------------------------------------------------------
    def task(self, num: int) -> Task:
        T = self.rt.tasks.get(num)
        if T is None or T.state not in ("running", "paused"):
            raise DebugError(f"task {num} is not running")
        return T

    def threads(self) -> list[tuple[int, str]]:
        """(task number, name) of every task that runs or is stopped."""
        return [(n, f"task {n} ({T.program})") for n, T in sorted(self.rt.tasks.items())
                if T.state in ("running", "paused")]

    def stop_on_entry(self, num: int) -> None:
        """The task stops before its first statement (set before it starts)."""
        self._entry.add(num)
        T = self.rt.tasks.get(num)
        if T is not None:
            T.trace = True

    def resume(self, num: int | None = None) -> None:
        """Continue one stopped task, or every one."""
        for n in ([num] if num is not None else list(self.stopped)):
            self._release(n)

    def _release(self, num: int) -> None:
        self.stopped.pop(num, None)
        T = self.rt.tasks.get(num)
        if T is not None and T.held:
            self.rt.release(T)

    def step(self, num: int, kind: str) -> None:
        """Step ``in``, ``over`` or ``out`` from where task ``num`` is stopped."""
        T = self.task(num)
        if num not in self.stopped or not T.frames:
            raise DebugError(f"task {num} is not stopped")
        self._steps[num] = _Step(kind, len(T.frames))
        T.trace = True
        self._release(num)

    def pause(self, num: int | None = None) -> None:
        """Stop one task, or every one, before its next statement (a task waiting in READ or WAIT stops when
        the wait ends)."""
        for n, T in list(self.rt.tasks.items()):
            if (num is None or n == num) and T.state == "running" and not T.held:
                self._pause.add(n)
                T.trace = True

    def detach(self) -> None:
        """The session ends and leaves the program running (an attached debugger): no breakpoint, step or pause
        is left, the arm is braked (the safe side: a motion a stopped task had started does not go on), and the
        stopped tasks go on."""
        for key in list(self._by_file):
            self.set_breakpoints(key, [])
        self._steps.clear()
        self._pause.clear()
        self._entry.clear()
        for T in self.rt.tasks.values():
            T.trace = False
        robot = self.rt.robot
        if robot is not None:
            robot.brake(self.rt.now)
        self.resume()
        self.on_event = lambda name, body: None

    def end(self) -> None:
        """The session ends: the arm is braked, every task aborted."""
        robot = self.rt.robot
        if robot is not None:
            robot.brake(self.rt.now)
        for n in list(self.rt.tasks):
            self.rt.abort(n)
        self.stopped.clear()

    # -- inspection -------------------------------------------------------------------------------------------
    def frames(self, num: int) -> list[Frame]:
        """Task ``num``'s call stack, innermost first: where it is stopped, or (a task that runs on, read between
        the scheduler's rounds) where it waits or was preempted."""
        T = self.task(num)
        if T.held and T.frames is not None:
            return T.frames
        return suspended_stack(T.gen)

    def scopes(self, frame: Frame) -> dict[str, list[tuple[str, Any]]]:
        """The variables of a frame by scope: ``AUTO`` (arguments first), ``LOCAL``, ``Globals``."""
        autos = [(name, value) for name, value, _ in frame.args()]
        autos += _named(frame.autos)
        return {"AUTO": autos, "LOCAL": _named(frame.statics), "Globals": _named(self.rt.globals)}

    def evaluate(self, text: str, frame: Frame | None) -> Any:
        """The value of V+ expression ``text`` in ``frame`` (None: globals only)."""
        code, ns, local = self._compile(text, frame, None)
        try:
            return eval(code, ns, local)  # noqa: S307 - V+ code compiled by our own compiler
        except Exception as exc:  # noqa: BLE001 - any run-time error of the expression is the user's
            raise DebugError(self.rt.as_vplus(exc).message or str(exc)) from None

    def set_variable(self, frame: Frame | None, name: str, value: str) -> Any:
        """Assign V+ expression ``value`` to variable ``name`` (``a``, ``$s``, ``a[3]``) as an assignment in
        ``frame`` would (a location with SET); returns the new value."""
        code, ns, local = self._compile(value, frame, name)
        try:
            exec(code, ns, local)  # noqa: S102 - V+ code compiled by our own compiler
        except Exception as exc:  # noqa: BLE001
            raise DebugError(self.rt.as_vplus(exc).message or str(exc)) from None
        return self.evaluate(name, frame)

    def _compile(self, text: str, frame: Frame | None, target: str | None) -> tuple[Any, dict, dict]:
        prog = frame.prog if frame is not None else Program("", [], "", 0)
        try:
            e = _expr(text)
            gen = _Gen(prog, self.rt.doubles(), traced=True)
            gen.declare(prog.steps)
            if target is None:
                src, mode = gen.val(e)[0], "eval"
            else:
                t = _expr(target)
                if not isinstance(t, (N.Name, N.Index)):
                    raise DebugError(f"{target}: not a variable")
                code, typ = gen.val(e)
                src, mode = gen.store(t, code, typ, force_loc=typ == "loc"), "exec"
            code_obj = compile(src, "<V+ expression>", mode)
        except VSyntaxError as exc:
            raise DebugError(f"{text}: {exc.message}") from None
        except Exception as exc:  # noqa: BLE001 - CompileError and the like: the user's expression
            raise DebugError(f"{text}: {getattr(exc, 'message', exc)}") from None
        if frame is not None:
            ns, local = frame.pyframe.f_globals, dict(frame.pyframe.f_locals)
        else:
            any_prog = next(iter(self.rt.programs.values()), None)
            if any_prog is None:
                raise DebugError("no program is loaded")
            ns, local = any_prog.__globals__, {"G": self.rt.globals, "_F": [0.0], "L": {}}
        local.setdefault("T", next(iter(self.rt.tasks.values()), None))
        ns = dict(ns, _K=gen.consts)            # the expression's own constants
        return code_obj, ns, local


def _expr(text: str) -> N.Expr:
    p = Parser(tokenize(text))
    e = p.expr()
    p.expect_end()
    return e


def _depth(frame: Frame) -> int:
    n = 0
    f = frame.pyframe
    while f is not None:
        if is_program_frame(f):
            n += 1
        f = f.f_back
    return n


def _named(d: dict) -> list[tuple[str, Any]]:
    return sorted(d.items(), key=lambda kv: kv[0])


def _true(v: Any) -> bool:
    return bool(v) if not isinstance(v, float) else v != 0.0


def _hit_ok(hits: int, cond: str) -> bool:
    m = _HIT_RE.match(cond)
    assert m is not None
    op, n = m.group(1) or ">=", int(m.group(2))
    if op == "%":
        return n > 0 and hits % n == 0
    return {">=": hits >= n, "<=": hits <= n, "==": hits == n, ">": hits > n, "<": hits < n}[op]


def _same_file(path: str) -> str:
    return os.path.normcase(os.path.realpath(path))


def render(v: Any) -> str:
    """A value as V+ would show it: numbers without a needless fraction, strings quoted, locations by their six
    components, precision points by their joints, arrays by their element count."""
    if isinstance(v, bool):
        return "TRUE" if v else "FALSE"
    if isinstance(v, float):
        return str(int(v)) if v.is_integer() and abs(v) < 1e15 else f"{v:.7g}"
    if isinstance(v, str):
        return '"' + v.replace('"', '""') + '"'
    if isinstance(v, Transform):
        return "TRANS(" + ", ".join(f"{x:.3f}" for x in v.decompose()) + ")"
    if isinstance(v, PrecisionPoint):
        return "#PPOINT(" + ", ".join(f"{x:.3f}" for x in v.joints_deg) + ")"
    if isinstance(v, dict):
        return f"array [{len(v)}]"
    if v is None:
        return "(undefined)"
    return str(v)


def children(v: Any) -> list[tuple[str, Any]]:
    """The parts of a value shown under it: an array's elements, a location's x y z yaw pitch roll, a precision
    point's joints; [] for a number or a string."""
    if isinstance(v, Transform):
        return list(zip(("x", "y", "z", "yaw", "pitch", "roll"), v.decompose(), strict=True))
    if isinstance(v, PrecisionPoint):
        return [(f"j{i + 1}", x) for i, x in enumerate(v.joints_deg)]
    if isinstance(v, dict):
        return [(f"[{_index(k)}]", x) for k, x in sorted(v.items(), key=lambda kv: str(kv[0]))]
    return []


def _index(k: Any) -> str:
    if isinstance(k, tuple):
        return ",".join(map(str, k))
    return str(k)


__all__ = ["Breakpoint", "DebugError", "Debugger", "EXCEPTION_MODES", "Stop", "children", "render"]
