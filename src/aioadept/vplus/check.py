"""Every problem of a set of V+ source files, without running them: the core of ``aioadept vplus check`` and of
the language server's diagnostics.

The files are loaded together as one module (the way ``aioadept sim --vplus`` loads them) and every program
that loaded is compiled, so the problems are those the emulator reports at load time, all at once: the
loader's (syntax, data sections, programs not closed) and the compiler's (labels, blocks, names, arguments).
Pure: text in, problems out; nothing is read from disk and nothing runs.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from aioadept.vplus.compiler import compile_program
from aioadept.vplus.loader import LoadProblem, Module, load_text


@dataclass(frozen=True, slots=True)
class Problem:
    """One problem: ``file`` as given to :func:`check`, 1-based ``line`` and ``column`` (1 where the loader
    does not know the column), ``end_column`` the column after the offending word, ``message`` with the
    program it is in and the word, ``severity`` ``error`` (what V+ refuses to load)."""

    file: str
    line: int
    column: int
    end_column: int
    message: str
    severity: str = "error"

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}: {self.severity}: {self.message}"


def check(sources: Iterable[tuple[str, str]]) -> list[Problem]:
    """The problems of ``sources``, ``(file name, text)`` pairs loaded together, sorted by file order, line and
    column."""
    module = Module()
    order: dict[str, int] = {}
    for name, text in sources:
        order.setdefault(name, len(order))
        load_text(text, name, module)
    found = list(module.problems)
    for prog in module.programs.values():
        if prog.executable:
            found.extend(compile_program(prog, set())[2])
    out = {_problem(p) for p in found}     # a program defined twice is compiled once, but dedupe anyway
    return sorted(out, key=lambda p: (order.get(p.file, len(order)), p.line, p.column, p.message))


def _problem(p: LoadProblem) -> Problem:
    where = f" in {p.program}" if p.program else ""
    word = f" [{p.word}]" if p.word else ""
    col = p.column or 1
    end = col + len(p.word) if p.column and p.word else col + 1
    return Problem(p.file, p.line, col, end, f"{p.message}{where}{word}")
