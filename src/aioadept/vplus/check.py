"""Every problem of a set of V+ source files, without running them: the core of ``aioadept vplus check`` and of
the language server's diagnostics.

Each file is read by the emulator's loader and every program that loaded is compiled, so the errors are
those the emulator reports at load time, all at once: the loader's (syntax, data sections, programs not closed)
and the compiler's (labels, blocks, names, arguments); a program defined twice has both definitions checked.
Warnings (asked for) are what V+ loads but fails on or is very likely wrong (:mod:`aioadept.vplus.lint`), over
all the files together; a line's ``; check: ignore W101`` comment silences that warning there.
Pure: text in, problems out; nothing is read from disk and nothing runs.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from urllib.parse import quote

from aioadept import __version__
from aioadept.vplus import lint
from aioadept.vplus.compiler import compile_program
from aioadept.vplus.loader import LoadProblem, Module, load_text

ERROR = "E001"
"""The code of every error: a line or program that V+ (and the emulator) refuses to load."""
CODES = {ERROR: "V+ refuses to load this: syntax, an unknown word, labels, blocks, names, arguments or a data "
                "section", **lint.CODES}
"""Every problem's code and what it means."""


@dataclass(frozen=True, slots=True)
class Problem:
    """One problem: ``file`` as given to :func:`check`, 1-based ``line`` and ``column`` (1 where the loader
    does not know the column), ``end_column`` the column after the offending word, ``message`` with the
    program it is in and the word, ``severity`` ``error`` (what V+ refuses to load) or ``warning``, ``code``
    (:data:`CODES`)."""

    file: str
    line: int
    column: int
    end_column: int
    message: str
    severity: str = "error"
    code: str = ERROR

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}: {self.severity}: {self.message} [{self.code}]"


def check(sources: Iterable[tuple[str, str]], *, warnings: bool = False) -> list[Problem]:
    """The problems of ``sources``, ``(file name, text)`` pairs loaded together, sorted by file order, line and
    column: the errors, and with ``warnings`` the warnings not silenced on their line."""
    order: dict[str, int] = {}
    found: list[LoadProblem] = []
    pieces: list[_Piece] = []
    texts: dict[str, str] = {}
    for name, text in sources:
        order.setdefault(name, len(order))
        texts[name] = text
        for first, piece in _file_pieces(name, text):
            found.extend(replace(p, line=p.line + first - 1) for p in piece.problems)
            pieces.append((first, piece))
    out = {_problem(p) for p in found}
    if warnings:
        out.update(_warnings(pieces, texts))
    return sorted(out, key=lambda p: (order.get(p.file, len(order)), p.line, p.column, p.message))


def check_document(name: str, text: str, workspace: Iterable[tuple[str, str]] = ()) -> list[Problem]:
    """The errors and warnings of one document (a language server's diagnostics): ``workspace``, the other
    files ``(file name, text)`` (a file named ``name`` among them is left out: ``text`` is its current text),
    is loaded with it, so that their programs and assignments count, but their own problems are not reported."""
    sources = [(name, text), *((n, t) for n, t in workspace if n != name)]
    return [p for p in check(sources, warnings=True) if p.file == name]


@dataclass(frozen=True, slots=True)
class _Checked:
    """One piece of a file checked: its errors, its programs' lint facts and the variables its data sections
    assign, lines counted from the piece's first."""

    problems: tuple[LoadProblem, ...]
    facts: tuple[lint.Facts, ...]
    data: frozenset[str]


_Piece = tuple[int, _Checked]

_CHECKED: dict[tuple[str, str], _Checked] = {}
"""Each piece of a file (:func:`split_pieces`) checked, by (file name, text): after an edit only the pieces it changed
are parsed, compiled and analysed again (a language server checks on every keystroke), and a piece that only
moved (lines inserted above it) is not. Bounded: cleared when it grows past 4096."""


def _file_pieces(name: str, text: str) -> list[_Piece]:
    out: list[_Piece] = []
    for first, piece in split_pieces(text):
        checked = _CHECKED.get((name, piece))
        if checked is None:
            if len(_CHECKED) >= 4096:
                _CHECKED.clear()
            module = load_text(piece, name, Module())
            problems = list(module.problems)
            for prog in module.programs.values():
                if prog.executable:
                    problems.extend(compile_program(prog, set())[2])
            checked = _CHECKED[(name, piece)] = _Checked(
                tuple(problems), tuple(lint.facts(prog) for prog in module.programs.values()),
                frozenset(lint.data_keys(module.data)))
        # no problem's message names a line, so moving a piece only moves its problems' line numbers
        out.append((first, checked))
    return out


_IGNORE = re.compile(r";.*?\bcheck:\s*ignore\b\s*([A-Za-z]\d+(?:\s*,\s*[A-Za-z]\d+)*)?", re.IGNORECASE)


def ignored(text: str) -> dict[int, frozenset[str] | None]:
    """The warnings silenced on each line of ``text`` by a ``; check: ignore W101, W103`` comment (``None``:
    ``; check: ignore`` without codes, every warning of the line)."""
    out: dict[int, frozenset[str] | None] = {}
    if "check:" not in text.lower():
        return out
    for n, line in enumerate(text.replace("\r\n", "\n").replace("\r", "\n").split("\n"), 1):
        m = _IGNORE.search(line)
        if m is not None:
            out[n] = frozenset(c.strip().upper() for c in m.group(1).split(",")) if m.group(1) else None
    return out


def _warnings(pieces: list[_Piece], texts: dict[str, str]) -> list[Problem]:
    facts = [f.moved(first - 1) for first, piece in pieces for f in piece.facts]
    data = set().union(*(piece.data for _, piece in pieces))
    quiet = {name: ignored(text) for name, text in texts.items()}
    out = []
    for w in lint.warnings(facts, data):
        silenced = quiet.get(w.file, {})
        if w.line in silenced and (silenced[w.line] is None or w.code in silenced[w.line]):
            continue
        out.append(Problem(w.file, w.line, w.column, w.end_column, w.message, "warning", w.code))
    return out


def sarif(problems: Iterable[Problem]) -> dict:
    """The problems as a SARIF 2.1.0 log (OASIS Static Analysis Results Interchange Format), which code
    scanning services (GitHub's among them) take from CI: one run of this tool, every code as a rule, each
    problem a result at its file, line and columns. A relative file name stays relative (to the folder the
    check ran in: the repository's root in CI); an absolute one becomes a ``file:`` URI."""
    codes = list(CODES)
    results = []
    for p in problems:
        path = Path(p.file)
        uri = path.as_uri() if path.is_absolute() else quote(path.as_posix())
        results.append({
            "ruleId": p.code, "ruleIndex": codes.index(p.code), "level": p.severity,
            "message": {"text": p.message},
            "locations": [{"physicalLocation": {
                "artifactLocation": {"uri": uri},
                "region": {"startLine": p.line, "startColumn": p.column, "endColumn": p.end_column}}}]})
    rules = [{"id": code, "name": code, "shortDescription": {"text": text},
              "defaultConfiguration": {"level": "error" if code == ERROR else "warning"}}
             for code, text in CODES.items()]
    return {"$schema": "https://json.schemastore.org/sarif-2.1.0.json", "version": "2.1.0",
            "runs": [{"tool": {"driver": {"name": "aioadept vplus check", "version": __version__, "rules": rules}},
                      "columnKind": "unicodeCodePoints", "results": results}]}


def split_pieces(text: str) -> list[tuple[int, str]]:
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
