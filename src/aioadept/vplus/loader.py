"""Reading ``.V2`` module files: programs (``.PROGRAM name(args)`` ... ``.END``) and data sections.

A file is a sequence of sections. Programs are parsed line by line with :mod:`aioadept.vplus.parse`; a line
that cannot be parsed is recorded as a :class:`LoadProblem` (file, line, offending word) and marks its program
not executable, as the controller does when it loads a program with a bad step, while everything else loads.

Data sections, as controller-saved files carry them (one value per line, ``name value...``):

- ``.LOCATIONS``: a transformation as ``STORE`` writes it, ``name`` and the 12 components of its 3x4 matrix
  *stored by column* (V+ Language Reference Guide, ``TRANSB``/``$TRANSB``: the x, y and z axes of the rotation,
  then the position), which a controller writes over two lines (the second line has no name); or, as the
  emulator's own shorthand, ``name x y z yaw pitch roll`` on one line; ``#name j1 ... jn`` is a precision point
  (its values may also continue on the next line). A location that cannot be read exactly (another count, a
  matrix whose rotation is not a rotation) is not defined and is reported on its name, never loaded as a
  different value;
- ``.PRECISION POINTS``: ``#name j1 ... jn`` (the ``#`` may be omitted);
- ``.REALS`` and ``.DOUBLES``: ``name value``; ``.STRINGS``: ``$name "text"``.

Array elements are written ``name[i]`` in all of them. Form feeds (ASCII 12) and SUB (ASCII 26), which Adept
DeskTop writes between programs, are ignored.
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aioadept.vplus.compiler import compile_program
from aioadept.vplus.parse import VSyntaxError, norm, parse_statement
from aioadept.vplus.program import LoadProblem, Param, Program

__all__ = ["LoadProblem", "Module", "Param", "Program", "load_files", "load_text", "strip_comment"]


@dataclass(slots=True)
class Module:
    """What a set of files defines: programs by name, data values by variable name (see :meth:`data`)."""

    programs: dict[str, Program] = field(default_factory=dict)
    data: list[tuple[str, str, Any, Any]] = field(default_factory=list)   # (kind, name, index, value)
    problems: list[LoadProblem] = field(default_factory=list)
    files: list[str] = field(default_factory=list)


_PROG_RE = re.compile(r"\.PROGRAM\s+([A-Za-z][A-Za-z0-9._]*)\s*(?:\((.*)\))?\s*(?:;.*)?\Z", re.IGNORECASE)
_SECTIONS = {".LOCATIONS": "LOC", ".PRECISIONPOINTS": "PPOINT", ".PRECISION POINTS": "PPOINT", ".REALS": "REAL",
             ".DOUBLES": "DOUBLE", ".STRINGS": "STRING"}


def strip_comment(line: str) -> str:
    """The line without its ``;`` comment (a ``;`` inside a string constant does not start one)."""
    if ";" not in line:
        return line
    in_str = False
    for i, ch in enumerate(line):
        if ch == '"':
            in_str = not in_str
        elif ch == ";" and not in_str:
            return line[:i]
    return line


def _params(text: str | None, file: str, line: int, problems: list[LoadProblem]) -> list[Param]:
    out: list[Param] = []
    for raw in (text or "").split(","):
        raw = raw.strip()
        if not raw:
            continue
        m = re.fullmatch(r"([$#]?[A-Za-z][A-Za-z0-9._]*)\s*(\[\s*\])?", raw)
        if not m:
            problems.append(LoadProblem(file, line, "bad parameter", raw, None))
            continue
        out.append(Param(norm(m.group(1)), bool(m.group(2))))
    return out


def load_files(paths: list[str | Path], module: Module | None = None) -> Module:
    """Read the files into ``module`` (a new one by default); later definitions replace earlier ones."""
    module = module or Module()
    for path in paths:
        path = Path(path)
        text = path.read_bytes().decode("latin-1")
        load_text(text, path.name, module)
        module.files.append(str(path))
    return module


_PARSED: dict[tuple[str, str], Module] = {}
"""Parsed files by (content hash, file name): loading the same text again (every test of a V+ file loads it)
reuses the parsed programs, which nothing changes after loading. Bounded: cleared when it grows past 256."""


def load_text(text: str, filename: str, module: Module) -> Module:
    """Parse ``text`` (the contents of ``filename``) into ``module``; returns ``module``."""
    key = (hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest(), filename)
    parsed = _PARSED.get(key)
    if parsed is None:
        if len(_PARSED) >= 256:
            _PARSED.clear()
        parsed = _PARSED[key] = _parse_text(text, filename, Module())
    module.programs.update(parsed.programs)
    module.data.extend(parsed.data)
    module.problems.extend(parsed.problems)
    return module


def _parse_text(text: str, filename: str, module: Module) -> Module:
    reader = _Reader(filename, module)
    n = 0
    for n, raw in enumerate(text.replace("\r\n", "\n").replace("\r", "\n").split("\n"), 1):
        reader.line(n, raw.replace("\x0c", "").replace("\x1a", ""))
    reader.close(n)
    return module


class _Reader:
    """The state of reading one file line by line: the program or data section it is in."""

    def __init__(self, filename: str, module: Module) -> None:
        self.filename, self.module = filename, module
        self.cur: Program | None = None
        self.section: str | None = None
        self.pending: tuple | None = None         # a location whose values may continue on the next line

    def problem(self, n: int, line: str, message: str, word: str, program: str | None) -> LoadProblem:
        """A problem at ``word`` of ``line`` (its column where the word is found)."""
        return LoadProblem(self.filename, n, message, word, program, line.find(word) + 1 if word else 0)

    def line(self, n: int, line: str) -> None:
        head = line.strip()
        up = head.upper()
        if self.cur is None and self.section is None:
            self.outside(n, line, head)
        elif up == ".END":
            if self.cur is not None:
                _finish(self.cur, self.module)
            self.flush()
            self.cur, self.section = None, None
        elif self.section is not None:
            self.data(n, line)
        elif up.startswith(".PROGRAM"):
            self.module.problems.append(self.problem(n, line, ".PROGRAM before .END", head.split()[0],
                                                     self.cur.name))
            _finish(self.cur, self.module)
            m = _PROG_RE.match(strip_comment(head).strip())
            self.cur = Program(norm(m.group(1)), _params(m.group(2), self.filename, n, []), self.filename, n) \
                if m else None
        else:
            self.statement(n, line)

    def outside(self, n: int, line: str, head: str) -> None:
        """A line between sections: ``.PROGRAM``, a data section's name, a comment or a problem."""
        if not head or head.startswith(";"):
            return
        # a comment after the .PROGRAM line may hold anything, parentheses too (User's Guide, "Program
        # Organization": ".PROGRAM program_name(parameter_list) ;Comment")
        m = _PROG_RE.match(strip_comment(head).strip())
        if m:
            probs: list[LoadProblem] = []
            cur = self.cur = Program(norm(m.group(1)), _params(m.group(2), self.filename, n, probs),
                                     self.filename, n)
            for pr in probs:
                cur.problems.append(self.problem(pr.line, line, pr.message, pr.word, cur.name))
            return
        key = " ".join(head.upper().split())
        if key in _SECTIONS:
            self.section = _SECTIONS[key]
            return
        self.module.problems.append(self.problem(n, line, "text outside .PROGRAM/.END", head.split()[0], None))

    def data(self, n: int, line: str) -> None:
        """A line of a data section; a location's values may continue on the next lines."""
        section, code = self.section, strip_comment(line).strip()
        if code and section in ("LOC", "PPOINT") and _CONTINUATION.match(code):
            # the second line of a stored transformation (or a long precision point): values, no name
            if self.pending is None:
                self.module.problems.append(self.problem(n, line, "values without a location name",
                                                         code.split()[0], None))
            else:
                self.pending[3].append((n, code))
            return
        self.flush()
        if code and section in ("LOC", "PPOINT"):
            self.pending = (section, n, code, [])
        elif code:
            try:
                self.module.data.append(_data_line(section, code))
            except (ValueError, VSyntaxError) as exc:
                self.module.problems.append(self.problem(n, line, f"bad {section} value: {exc}",
                                                         code.split()[0], None))

    def statement(self, n: int, line: str) -> None:
        """A line of a program: its statement node, or its problem (and on to the next line)."""
        cur = self.cur
        code = strip_comment(line).strip()
        if not code:
            return
        cur.source[n] = code
        col0 = cur.indent[n] = len(line) - len(line.lstrip())
        try:
            cur.steps.append((n, parse_statement(code, self.filename, n, col0)))
        except VSyntaxError as exc:
            cur.problems.append(LoadProblem(self.filename, n, exc.message, exc.word, cur.name, exc.col))

    def flush(self) -> None:
        if self.pending is not None:
            _flush_location(self.pending, self.filename, self.module)
            self.pending = None

    def close(self, n: int) -> None:
        """The end of the file: what is still open is a problem."""
        if self.cur is not None:
            self.module.problems.append(LoadProblem(self.filename, self.cur.line, "program not closed by .END",
                                                    self.cur.name, self.cur.name))
            _finish(self.cur, self.module)
        self.flush()
        if self.section is not None:
            self.module.problems.append(LoadProblem(self.filename, n, "data section not closed by .END",
                                                    self.section, None))


_CONTINUATION = re.compile(r"[-+.\d]")


def _flush_location(pending: tuple, filename: str, module: Module) -> None:
    """A location entry with its continuation lines: its value, or a problem on its name (never a guess)."""
    section, line, code, more = pending
    text = " ".join([code] + [c for _, c in more])
    try:
        module.data.append(_data_line(section, text))
    except (ValueError, VSyntaxError) as exc:
        name = code.split()[0]
        module.problems.append(LoadProblem(filename, line, f"location {name} not loaded: {exc}", name, None))


def _finish(prog: Program, module: Module) -> None:
    _check_rest(prog)
    module.programs[prog.name] = prog
    module.problems.extend(prog.problems)


_STRUCTURE = re.compile(r"\s*(\d|(IF|WHILE|FOR|CASE|DO|END|ELSE|VALUE|ANY|UNTIL)\b)", re.IGNORECASE)


def _check_rest(prog: Program) -> None:
    """A program with a line that did not parse gets the problems of its other lines too (labels, blocks,
    names, arguments: what compiling reports), so that one load shows them all; not when a bad line is a label
    or opens or closes a block, whose loss would make problems of lines that have none."""
    if not prog.problems or any(_STRUCTURE.match(prog.source.get(p.line, "")) for p in prog.problems):
        return
    prog.problems.extend(compile_program(prog, set())[2])


_DATA_NAME = re.compile(r"([$#]?[A-Za-z][A-Za-z0-9._]*)(?:\[([0-9,\s]+)\])?")


def _data_line(section: str, code: str) -> tuple[str, str, Any, Any]:
    m = _DATA_NAME.match(code)
    if not m:
        raise ValueError("expected a name")
    name = norm(m.group(1))
    index = None
    if m.group(2):
        parts = [int(p) for p in m.group(2).split(",")]
        index = parts[0] if len(parts) == 1 else tuple(parts)
    rest = code[m.end():].strip()
    if section == "STRING":
        s = re.fullmatch(r'"([^"]*)"', rest)
        if not s:
            raise ValueError("expected a quoted string")
        if not name.startswith("$"):
            name = "$" + name
        return ("STRING", name, index, s.group(1))
    nums = [float(v) for v in rest.replace(",", " ").split()]
    if not all(math.isfinite(v) for v in nums):
        raise ValueError("a value is not a finite number")
    if section in ("REAL", "DOUBLE"):
        if len(nums) != 1:
            raise ValueError("expected one number")
        return (section, name, index, nums[0])
    if section == "PPOINT" or name.startswith("#"):
        if not name.startswith("#"):
            name = "#" + name
        if not nums:
            raise ValueError("expected joint values")
        return ("PPOINT", name, index, tuple(nums))
    if len(nums) == 12:
        from aioadept.vplus.locations import by_column   # numpy: only a file with stored locations needs it

        return ("LOC", name, index, by_column(nums))
    if len(nums) != 6:
        raise ValueError(f"expected the 12 values of a stored transformation (or x y z yaw pitch roll), "
                         f"got {len(nums)}")
    return ("LOC", name, index, tuple(nums))
