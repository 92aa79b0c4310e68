"""Which lines of ``.V2`` files ran, recorded by the emulator itself: cheap enough for a whole test suite's
emulated servers, with no coverage.py in them (docs/vplus.md, "Line coverage of V+ code").

An ``aioadept sim --vplus`` started with the environment variable ``AIOADEPT_VPLUS_LINES=FOLDER`` runs its
programs in the instrumented form (:mod:`aioadept.vplus.trace`) under a :class:`LineRecorder` and, when it ends,
writes the (file, line) pairs that ran to ``FOLDER/lines-PID.json``. :func:`load` merges a folder's files and
:func:`table` prints them per file against :func:`executable_lines` (the pytest plugin ``tests/vplus_coverage.py``
does so at the end of ``make test``). The coverage.py plugin (:mod:`aioadept.vplus.coverage_plugin`) records
with the same tracer.

The recorder asks for the line hook at each statement of each program once: the first run of a line records it and
drops the hook, so from then on a statement costs the hook's two tests, whatever ran it before; the AUTO variables
stay Python locals as in the plain form (the recorder reads none).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from aioadept.vplus import nodes as N
from aioadept.vplus.compiler import compile_program
from aioadept.vplus.loader import Module, load_text

ENV = "AIOADEPT_VPLUS_LINES"
"""The environment variable naming the folder an ``aioadept sim --vplus`` writes its lines to."""


# -- the executable lines of a file ------------------------------------------------------------------------------

def executable_lines(text: str, filename: str = "") -> set[int]:
    """The lines of ``text`` where a statement runs: those the compiler puts a line hook before (every statement,
    and the heads of IF, WHILE, CASE and FOR), read from the instrumented form it generates. A program that does
    not compile (it cannot run) counts its statements by the same rule, as never run."""
    out: set[int] = set()
    for prog in load_text(text, filename, Module()).programs.values():
        if prog.executable:
            src, consts, problems = compile_program(prog, set(), traced=True)
            if src is not None:
                out.update(line for line in consts[-1] if line)
                continue
        out.update(line for line, st in prog.steps if _hooked(st))
    return out


_NOT_HOOKED = (N.Declare, N.Nop, N.Value, N.Until)


def _hooked(st: N.Stmt | None) -> bool:
    """Whether the compiler hooks a statement (the rule of its ``block``: declarations, a lone label and the
    block words DO, ELSE, END, VALUE, ANY, UNTIL have no hook of their own)."""
    if isinstance(st, N.Label):
        st = st.stmt
    if st is None or isinstance(st, _NOT_HOOKED):
        return False
    return not (isinstance(st, N.Word) and st.word in ("DO", "ELSE", "END", "ANY"))


# -- recording ---------------------------------------------------------------------------------------------------

class LineRecorder:
    """The emulator's tracer (:mod:`aioadept.vplus.trace`) for one runtime: each line of a file that exists is
    recorded the first time it runs (:meth:`record`), in ``hits``, and its hook dropped."""

    def __init__(self, rt: Any, hits: set[tuple[str, int]] | None = None) -> None:
        self.rt = rt
        self.hits: set[tuple[str, int]] = set() if hits is None else hits
        # the loader names each program's file by its base name; the module keeps the paths it loaded
        self.paths = {Path(f).name: os.path.abspath(f) for f in rt.module.files if os.path.isfile(f)}
        for name, prog in rt.module.programs.items():
            path = self.paths.get(prog.file)
            if path is not None:
                rt.trace_lines(name).update(line for line, _ in prog.steps if (path, line) not in self.hits)

    def line(self, task: Any, frame: Any) -> None:
        self.rt.trace_lines(frame.program).discard(frame.line)
        path = self.paths.get(frame.file)
        if path is not None and (path, frame.line) not in self.hits:
            self.hits.add((path, frame.line))
            self.record(path, frame.line)

    def record(self, path: str, line: int) -> None:
        """A line ran for the first time (it is in ``hits`` already)."""

    def error(self, task: Any, err: Any, frames: Any) -> None:
        """A V+ error: nothing to record (its line ran, and was recorded then)."""


def attach(rt: Any, hits: set[tuple[str, int]] | None = None, recorder: type[LineRecorder] = LineRecorder
           ) -> LineRecorder | None:
    """Record the lines ``rt`` runs (a :class:`aioadept.vplus.runtime.Runtime` with no task running); None for one
    whose programs come from no file (``Emulator.from_source``): there is no file to report."""
    tracer = recorder(rt, hits)
    if not tracer.paths:
        return None
    rt.set_tracer(tracer, variables=False)
    return tracer


def from_env(rt: Any) -> LineRecorder | None:
    """With ``AIOADEPT_VPLUS_LINES`` set: record ``rt``'s lines (:func:`save` writes them); else None. A recorder
    attached already (coverage.py's plugin) is kept and its lines saved; another tracer is never replaced."""
    if not os.environ.get(ENV):
        return None
    if isinstance(rt.tracer, LineRecorder):
        return rt.tracer
    return attach(rt) if rt.tracer is None else None


def save(recorder: LineRecorder | None) -> None:
    """Write the lines ``recorder`` saw to ``$AIOADEPT_VPLUS_LINES/lines-PID.json`` (nothing without either)."""
    folder = os.environ.get(ENV)
    if recorder is None or not folder:
        return
    by_file: dict[str, list[int]] = {}
    for path, line in sorted(recorder.hits):
        by_file.setdefault(path, []).append(line)
    out = Path(folder) / f"lines-{os.getpid()}.json"
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(by_file))
    tmp.replace(out)        # a reader never sees half a file


# -- reporting ---------------------------------------------------------------------------------------------------

def load(folder: str | Path) -> dict[str, set[int]]:
    """The lines that ran by file, merged over every ``lines-*.json`` in ``folder``."""
    out: dict[str, set[int]] = {}
    for f in sorted(Path(folder).glob("lines-*.json")):
        for path, lines in json.loads(f.read_text()).items():
            out.setdefault(path, set()).update(lines)
    return out


def ranges(lines: set[int]) -> str:
    """``{3, 4, 5, 9}`` -> ``"3-5, 9"``."""
    runs: list[list[int]] = []
    for n in sorted(lines):
        if runs and n == runs[-1][1] + 1:
            runs[-1][1] = n
        else:
            runs.append([n, n])
    out = [str(a) if a == b else f"{a}-{b}" for a, b in runs]
    return ", ".join(out)


def report(hits: dict[str, set[int]], files: list[str | Path]) -> list[tuple[str, int, int, set[int]]]:
    """Per file of ``files``: (path, executable lines, lines run, the executable lines not run)."""
    out = []
    for f in files:
        path = os.path.abspath(f)
        exe = executable_lines(Path(path).read_bytes().decode("latin-1"), Path(path).name)
        ran = hits.get(path, set()) & exe
        out.append((path, len(exe), len(ran), exe - ran))
    return out


def table(rows: list[tuple[str, int, int, set[int]]], root: str | Path = ".") -> str:
    """``report``'s rows as coverage.py's ``report -m`` prints them, with a total line."""
    def name(p: str) -> str:
        return os.path.relpath(p, root)

    width = max([len(name(r[0])) for r in rows] + [5])
    lines = [f"{'Name':<{width}}  Stmts   Miss  Cover   Missing", "-" * (width + 32)]
    for path, exe, ran, missed in rows:
        lines.append(f"{name(path):<{width}}  {exe:>5}  {exe - ran:>5}  {_pct(ran, exe):>5}   {ranges(missed)}".rstrip())
    exe, ran = sum(r[1] for r in rows), sum(r[2] for r in rows)
    lines += ["-" * (width + 32), f"{'TOTAL':<{width}}  {exe:>5}  {exe - ran:>5}  {_pct(ran, exe):>5}"]
    return "\n".join(lines)


def _pct(ran: int, exe: int) -> str:
    return f"{100 * ran // exe if exe else 100}%"
