"""Where the names of V+ source files are defined and used: the core of the language server's go to definition,
find references, document and workspace symbols and completion in scope.

A file's *occurrences* are read from the emulator's loader (its programs' statement nodes, :mod:`.nodes`) and
the line's tokens (for the exact column of a name the nodes keep only by value, such as a ``CALL`` target):

- a program name: its ``.PROGRAM`` line (the definition), each ``CALL``, ``EXECUTE`` and ``REACTE`` of it;
- a step label: the labelled line (the definition) and each ``GOTO`` and ``IF ... GOTO`` of it, in its program;
- a variable: a parameter or an ``AUTO``/``LOCAL`` name is its program's own (V+ Language User's Guide,
  "Variable Classes": a variable nothing declares is global); a global is defined by its ``GLOBAL``
  declarations or, where none declares it, by the statements that assign it.

Pure: ``(file name, text)`` pairs in, occurrences out; nothing is read from disk and nothing runs.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

from aioadept.vplus import nodes as N
from aioadept.vplus.check import split_pieces
from aioadept.vplus.loader import Module, load_text
from aioadept.vplus.parse import VSyntaxError, norm, tokenize
from aioadept.vplus.program import Program

PROGRAM, LABEL, VARIABLE = "program", "label", "variable"
DEFINITION, ASSIGN, USE = "definition", "assign", "use"


@dataclass(frozen=True, slots=True)
class Occurrence:
    """One use of a name: ``file``, 1-based ``line``, first column ``col`` and the column after it ``end``;
    ``kind`` program, label or variable; ``name`` normalised (a label's number as text); ``scope`` the line of
    the ``.PROGRAM`` a label or local variable belongs to (0: a program or global name); ``role`` definition
    (``.PROGRAM`` line, labelled line, parameter, declaration), assign or use; ``program`` the program it is in."""

    file: str
    line: int
    col: int
    end: int
    kind: str
    name: str
    scope: int
    role: str
    program: str = ""

    @property
    def key(self) -> tuple:
        """What the occurrence names: equal for every occurrence of the same program, label or variable."""
        return (self.kind, self.name, self.file if self.scope else "", self.scope)


@dataclass(slots=True)
class FileSymbols:
    """What one file defines and uses: its programs, each as ``(program, its .PROGRAM line, its .END line)`` in
    this file (a program's own line numbers are those of the piece it was read from), and occurrences."""

    file: str
    programs: list[tuple[Program, int, int]] = field(default_factory=list)
    occurrences: list[Occurrence] = field(default_factory=list)
    locals: dict[int, set[str]] = field(default_factory=dict)      # per .PROGRAM line: its parameters, AUTO, LOCAL

    def at(self, line: int, col: int) -> Occurrence | None:
        """The occurrence that the 1-based ``col`` of ``line`` is in (or just after)."""
        for o in self.occurrences:
            if o.line == line and o.col <= col <= o.end:
                return o
        return None

    def program_at(self, line: int) -> tuple[Program, int, int] | None:
        """The program whose ``.PROGRAM`` ... ``.END`` holds ``line``."""
        for entry in self.programs:
            if entry[1] <= line <= entry[2]:
                return entry
        return None


_CACHE: dict[tuple[str, str, int], FileSymbols] = {}
"""The pieces of files (:func:`aioadept.vplus.check.split_pieces`, cut after each ``.END``) by (file name, text, the
line where the piece starts): after an edit only the changed program is read again (and, when lines were
inserted or deleted, the programs below it are moved). Bounded: cleared when it grows past 4096."""
_LATEST: dict[str, tuple[str, FileSymbols]] = {}
"""Each file's last text and what it holds: the server asks again for every request, mostly of unchanged text."""


def file_symbols(file: str, text: str) -> FileSymbols:
    """The programs and occurrences of ``text``, the contents of ``file``."""
    last = _LATEST.get(file)
    if last is not None and last[0] == text:
        return last[1]
    got = FileSymbols(file)
    for first, piece in split_pieces(text):
        part = _piece(file, piece, first)
        got.programs.extend(part.programs)
        got.locals.update(part.locals)
        got.occurrences.extend(part.occurrences)
    _LATEST[file] = (text, got)
    return got


def _piece(file: str, piece: str, first: int) -> FileSymbols:
    got = _CACHE.get((file, piece, first))
    if got is None:
        got = _CACHE.get((file, piece, 1)) or _keep((file, piece, 1), _read(file, piece))
        if first != 1:
            d = first - 1
            got = _keep((file, piece, first), FileSymbols(
                file, [(prog, start + d, end + d) for prog, start, end in got.programs],
                [Occurrence(o.file, o.line + d, o.col, o.end, o.kind, o.name, o.scope + d if o.scope else 0, o.role,
                            o.program) for o in got.occurrences],
                {start + d: names for start, names in got.locals.items()}))
    return got


def _keep(key: tuple[str, str, int], value: FileSymbols) -> FileSymbols:
    """Keep ``value`` under ``key`` in the pieces' cache."""
    if len(_CACHE) >= 4096:
        _CACHE.clear()
    _CACHE[key] = value
    return value


_NAME = re.compile(r"[$#]?[A-Za-z][A-Za-z0-9._]*")
_PROG_LINE = re.compile(r"\s*\.PROGRAM\s+([A-Za-z][A-Za-z0-9._]*)\s*(\(([^)]*)\))?", re.IGNORECASE)
_TYPES = {"REAL", "DOUBLE", "LOC", "PRECISION"}


def _read(file: str, text: str) -> FileSymbols:
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    module = load_text(text, file, Module())
    out = FileSymbols(file)
    for prog in sorted(module.programs.values(), key=lambda p: p.line):
        if prog.file != file:
            continue
        end = next((n for n in range(prog.line + 1, len(lines) + 1)
                    if lines[n - 1].replace("\x0c", "").replace("\x1a", "").strip().upper() == ".END"), len(lines))
        out.programs.append((prog, prog.line, end))
        out.occurrences.extend(_program_occurrences(prog, lines[prog.line - 1], out.locals))
    return out


def _program_occurrences(prog: Program, head: str, local_names: dict[int, set[str]]) -> list[Occurrence]:
    found: list[tuple[int, int, int, str, str, str]] = []     # (line, col, end, kind, name, role)
    m = _PROG_LINE.match(head)
    if m:
        found.append((prog.line, m.start(1) + 1, m.end(1) + 1, PROGRAM, norm(m.group(1)), DEFINITION))
        if m.group(3) is not None:
            for w in _NAME.finditer(m.group(3)):
                col = m.start(3) + w.start() + 1
                found.append((prog.line, col, col + len(w.group()), VARIABLE, norm(w.group()), DEFINITION))
    mine = {p.name for p in prog.params}
    for line, stmt in prog.steps:
        code, indent = prog.source[line], prog.indent.get(line, 0)
        try:
            toks = tokenize(code)
        except VSyntaxError:
            continue
        cols = {indent + t.col + 1: t for t in toks}
        for kind, name, role, tok in _statement(stmt, toks):
            found.append((line, indent + tok.col + 1, indent + tok.col + 1 + len(tok.text), kind, name, role))
            if kind == VARIABLE and role == DEFINITION and _declared(stmt) in ("AUTO", "LOCAL"):
                mine.add(name)
        for node, role in _variables(stmt):
            tok = cols.get(node.span.col)
            if tok is not None:
                found.append((line, node.span.col, node.span.col + len(tok.text), VARIABLE, node.name, role))
    local_names[prog.line] = mine
    out = []
    for line, col, end, kind, name, role in found:
        scoped = kind == LABEL or (kind == VARIABLE and name in mine)
        out.append(Occurrence(prog.file, line, col, end, kind, name, prog.line if scoped else 0, role, prog.name))
    return out


def _declared(stmt: N.Stmt) -> str:
    stmt = stmt.stmt if isinstance(stmt, N.Label) else stmt
    return stmt.word if isinstance(stmt, N.Declare) else ""


def _statement(stmt: N.Stmt, toks: list) -> Iterator[tuple[str, str, str, object]]:
    """The program names, labels and declared variables of one statement, each with its token."""
    if isinstance(stmt, N.Label):
        yield LABEL, str(stmt.number), DEFINITION, toks[0]
        toks = toks[1:]
        stmt = stmt.stmt
    words = [t.text.upper() if t.kind == "name" else t.text for t in toks]
    if isinstance(stmt, (N.Goto, N.IfGoto)) and "GOTO" in words:
        k = len(words) - 1 - words[::-1].index("GOTO")
        if k + 1 < len(toks):
            yield LABEL, str(stmt.label), USE, toks[k + 1]
    elif isinstance(stmt, (N.CallStmt, N.Execute, N.Reacte)):
        tok = next((t for t in toks[1:] if t.kind == "name" and norm(t.text) == stmt.name), None)
        if tok is not None:
            yield PROGRAM, stmt.name, USE, tok
    elif isinstance(stmt, N.Declare):
        declared = {name for name, _, _ in stmt.names}
        for t in toks[1:]:
            if t.kind == "name" and t.text.upper() not in _TYPES and norm(t.text) in declared:
                yield VARIABLE, norm(t.text), DEFINITION, t


def _variables(stmt: N.Node) -> Iterator[tuple[N.Expr, str]]:
    """The variables a statement's nodes name (scalars, array elements, whole arrays), each with its role."""
    assigned: set[int] = set()
    inner = stmt.stmt if isinstance(stmt, N.Label) else stmt
    if isinstance(inner, N.Assign):
        assigned.add(id(inner.target))
    elif isinstance(inner, N.For):
        assigned.add(id(inner.var))
    elif isinstance(inner, (N.Here, N.Decompose)):
        assigned.add(id(inner.target))
    elif isinstance(inner, N.Read):
        assigned.update(id(t) for t in inner.targets)
    elif isinstance(inner, N.Prompt):
        assigned.update(id(t) for t in inner.items)
    stack: list[N.Node] = [stmt]
    while stack:
        node = stack.pop()
        if isinstance(node, (N.Name, N.Index, N.Array)):
            yield node, ASSIGN if id(node) in assigned else USE
        stack.extend(node.children())


class Workspace:
    """The occurrences of a set of files, and what the language server asks of them."""

    def __init__(self, sources: Iterable[tuple[str, str]]) -> None:
        self.files: dict[str, FileSymbols] = {name: file_symbols(name, text) for name, text in sources}
        self._by_key: dict[tuple, list[Occurrence]] | None = None

    def _same(self, target: Occurrence) -> list[Occurrence]:
        if self._by_key is None:
            self._by_key = {}
            for o in self.occurrences():
                self._by_key.setdefault(o.key, []).append(o)
        return self._by_key.get(target.key, [])

    def occurrences(self) -> Iterator[Occurrence]:
        for fs in self.files.values():
            yield from fs.occurrences

    def at(self, file: str, line: int, col: int) -> Occurrence | None:
        """The occurrence at 1-based ``line`` and ``col`` of ``file``."""
        fs = self.files.get(file)
        return fs.at(line, col) if fs else None

    def definitions(self, target: Occurrence) -> list[Occurrence]:
        """Where ``target``'s program, label or variable is defined (a global that nothing declares: where it
        is assigned)."""
        same = self._same(target)
        return [o for o in same if o.role == DEFINITION] or [o for o in same if o.role == ASSIGN]

    def references(self, target: Occurrence, *, declaration: bool = True) -> list[Occurrence]:
        """Every occurrence of ``target``'s program, label or variable (without its definitions unless
        ``declaration``)."""
        return [o for o in self._same(target) if declaration or o.role != DEFINITION]

    def programs(self) -> Iterator[tuple[Program, int, int]]:
        for fs in self.files.values():
            yield from fs.programs

    def in_scope(self, file: str, line: int) -> tuple[list[str], list[str]]:
        """The variables usable at ``line`` of ``file``: the enclosing program's own (parameters, ``AUTO``,
        ``LOCAL``) and the workspace's globals, each sorted."""
        fs = self.files.get(file)
        entry = fs.program_at(line) if fs else None
        own = sorted(fs.locals.get(entry[1], set())) if entry is not None else []
        glob = sorted({o.name for o in self.occurrences() if o.kind == VARIABLE and not o.scope} - set(own))
        return own, glob

    def symbols(self, query: str = "") -> list[Occurrence]:
        """The workspace's programs and ``GLOBAL`` variables whose name holds ``query`` (any case)."""
        q = query.lower()
        return [o for o in self.occurrences() if o.role == DEFINITION and not o.scope and q in o.name]
