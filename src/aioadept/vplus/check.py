"""Every problem of a set of V+ source files, without running them: the core of ``aioadept vplus check`` and of
the language server's diagnostics.

Each file is read by the emulator's loader and every program that loaded is compiled, so the problems are
those the emulator reports at load time, all at once: the loader's (syntax, data sections, programs not closed)
and the compiler's (labels, blocks, names, arguments); a program defined twice has both definitions checked.
Pure: text in, problems out; nothing is read from disk and nothing runs.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace

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
    """The problems of ``sources``, ``(file name, text)`` pairs, sorted by file order, line and column."""
    order: dict[str, int] = {}
    found: list[LoadProblem] = []
    for name, text in sources:
        order.setdefault(name, len(order))
        found.extend(_file_problems(name, text))
    out = {_problem(p) for p in found}
    return sorted(out, key=lambda p: (order.get(p.file, len(order)), p.line, p.column, p.message))


_CHECKED: dict[tuple[str, str], list[LoadProblem]] = {}
"""The problems of each piece of a file (:func:`_pieces`) by (file name, text), their lines counted from the
piece's first: after an edit only the pieces it changed are parsed and compiled again (a language server checks
on every keystroke), and a piece that only moved (lines inserted above it) is not. Bounded: cleared when it grows
past 4096."""


def _file_problems(name: str, text: str) -> list[LoadProblem]:
    out: list[LoadProblem] = []
    for first, piece in _pieces(text):
        problems = _CHECKED.get((name, piece))
        if problems is None:
            if len(_CHECKED) >= 4096:
                _CHECKED.clear()
            module = load_text(piece, name, Module())
            problems = list(module.problems)
            for prog in module.programs.values():
                if prog.executable:
                    problems.extend(compile_program(prog, set())[2])
            _CHECKED[(name, piece)] = problems
        # no problem's message names a line, so moving a piece only moves its problems' line numbers
        out.extend(replace(p, line=p.line + first - 1) for p in problems)
    return out


def _pieces(text: str) -> list[tuple[int, str]]:
    """``text`` cut after each ``.END`` line, as ``(first line, text)``. The loader reads a file line by line
    and every ``.END`` line (of a program, of a data section, or stray) leaves it as at the start of a file, so
    each piece loads as it does within the whole file."""
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    out: list[tuple[int, str]] = []
    first = 0
    for n, raw in enumerate(lines):
        if raw.replace("\x0c", "").replace("\x1a", "").strip().upper() == ".END":
            out.append((first + 1, "\n".join(lines[first:n + 1])))
            first = n + 1
    if first < len(lines):
        out.append((first + 1, "\n".join(lines[first:])))
    return out


def _problem(p: LoadProblem) -> Problem:
    where = f" in {p.program}" if p.program else ""
    word = f" [{p.word}]" if p.word else ""
    col = p.column or 1
    end = col + len(p.word) if p.column and p.word else col + 1
    return Problem(p.file, p.line, col, end, f"{p.message}{where}{word}")
