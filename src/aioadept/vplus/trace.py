"""Line hooks in the emulator: what a debugger (:mod:`aioadept.vplus.debugger`) or a line-coverage tool builds on.

Without a tracer the emulator runs the programs as compiled by :mod:`aioadept.vplus.compiler` (no hook, the same
code as ever). ``Emulator.set_tracer(tracer)`` (or ``Runtime.set_tracer``), called before tasks start, compiles
every program a second time in an *instrumented* form: before each V+ statement (and each IF, WHILE, CASE and
FOR head) it runs::

    if T.trace or LINE in _BP: yield from _dbg(T, LINE)

so the hook costs two tests per statement until it fires, and every AUTO variable lives in the call's ``L`` dict
(not a Python local), where a debugger reads and sets it.

To trace every runtime a process makes (a line-coverage tool), append a function to ``Runtime.on_new``: it is
called with each new runtime, its programs compiled and no task started, and may call ``set_tracer`` there.

**The tracer API** (any object with these two methods)::

    tracer.line(task: Task, frame: Frame) -> None
        before the statement at frame.file:frame.line runs in task.num, when
        - the line is in the set ``Runtime.trace_lines(program)`` (breakpoints: the tracer adds and removes lines),
        - or ``task.trace`` is true (stepping: the tracer sets it per task),
        - or always, with ``set_tracer(tracer, all_lines=True)`` (line coverage).
        ``task.frames`` holds the task's V+ call stack, innermost first (``frame`` is ``task.frames[0]``).
    tracer.error(task: Task, err: VPlusError, frames: list[Frame]) -> None
        a V+ error in a statement, before the task's REACTE program (if any) takes it or it stops the task.

Either method may *block the task*: set ``task.held = True`` and the task waits there (one trajectory cycle at a
time, as a WAIT: the other tasks run on) until ``Runtime.release(task)``. While it is held, ``task.frames`` stays
valid: each :class:`Frame` reads the program's AUTO, LOCAL and argument variables live. A tracer must not raise;
it runs inside the task's turn, so it must also be quick (line coverage: add the line to a set).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from types import FrameType
from typing import Any

from aioadept.vplus.program import Program


@dataclass(eq=False)
class Frame:
    """One V+ call of a task's stack: its program, file and current line, and its variables (live)."""

    program: str
    file: str
    line: int
    prog: Program
    pyframe: FrameType

    @property
    def autos(self) -> dict[str, Any]:
        """The call's AUTO variables (arrays under ``name[]``); a name not yet assigned is absent."""
        return self.pyframe.f_locals.get("L", {})

    @property
    def statics(self) -> dict[str, Any]:
        """The program's LOCAL variables in this task."""
        s = self.pyframe.f_locals.get("S")
        return s if isinstance(s, dict) else {}

    def args(self) -> list[tuple[str, Any, tuple[Any, Any] | None]]:
        """The parameters: (name, value or None if undefined, (container, key) to set a scalar or None)."""
        out: list[tuple[str, Any, tuple[Any, Any] | None]] = []
        loc = self.pyframe.f_locals
        for i, p in enumerate(self.prog.params):
            if p.is_array:
                out.append((p.name + "[]", loc.get(f"A{i}"), None))
                continue
            c, k = loc.get(f"P{i}c"), loc.get(f"P{i}k")
            try:
                out.append((p.name, c[k], (c, k)))
            except (KeyError, IndexError, TypeError):
                out.append((p.name, None, (c, k) if c is not None else None))
        return out


def is_program_frame(f: FrameType) -> bool:
    return f.f_code.co_name == "_prog" and "_PROG" in f.f_globals


def stack(innermost: FrameType, line: int | None) -> list[Frame]:
    """The V+ frames from the Python frame ``innermost`` outwards (while the task runs: its Python frames are
    linked). ``line``: the innermost program's V+ line (None: from its Python line, as for the callers)."""
    out: list[Frame] = []
    f: FrameType | None = innermost
    while f is not None:
        if is_program_frame(f):
            g = f.f_globals
            prog: Program = g["_PROG"]
            at = line if (line is not None and not out) else _vline(g["_K"][-1], f.f_lineno)
            out.append(Frame(prog.name, prog.file, at, prog, f))
        f = f.f_back
    return out


def _vline(line_of: tuple, pyline: int | None) -> int:
    if pyline is None or not 0 < pyline <= len(line_of):
        return 0
    return line_of[pyline - 1]


def caller() -> FrameType:
    """The Python frame that resumed the running generator (the program whose hook runs)."""
    return sys._getframe(2)


class Every:
    """The ``_BP`` of ``set_tracer(all_lines=True)``: contains every line."""

    def __contains__(self, _line: object) -> bool:
        return True


def suspended_stack(gen: Any) -> list[Frame]:
    """The V+ frames of a task that is not running now (between the scheduler's rounds), innermost first: its
    generators, each suspended where it yielded, from ``task.gen`` inwards."""
    out: list[Frame] = []
    while gen is not None:
        f = getattr(gen, "gi_frame", None)
        if f is not None and is_program_frame(f):
            prog: Program = f.f_globals["_PROG"]
            out.append(Frame(prog.name, prog.file, _vline(f.f_globals["_K"][-1], f.f_lineno), prog, f))
        gen = getattr(gen, "gi_yieldfrom", None)
    out.reverse()
    return out
