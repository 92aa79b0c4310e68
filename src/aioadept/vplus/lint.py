"""Warnings for V+ that loads but fails at run time or is very likely wrong: the analysis of ``aioadept vplus
check`` beyond what the emulator refuses at load time.

Two steps, so that a checker can keep the first per program between edits:

- :func:`facts` of one loaded :class:`~aioadept.vplus.program.Program`: what it reads, assigns and calls, and
  its warnings that need nothing else (labels, AUTOs, unreachable lines, long strings);
- :func:`warnings` of the facts of every program of the loaded modules (and their data sections): the warnings
  across modules (a variable nothing assigns, a program nobody defines, too many arguments).

Pure: loaded programs in, :class:`Finding` out; nothing is read from disk, parsed or run. The codes are in
:data:`CODES`; docs/vplus.md ("Checking V+ in the editor and in CI") says what each means and how to silence one.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field, replace

from aioadept.vplus import nodes as N
from aioadept.vplus.parse import norm
from aioadept.vplus.program import Program

CODES = {
    "W101": "a variable is read that nothing assigns in the loaded modules (V+ stops with *Undefined value*)",
    "W102": "a program is called that no loaded module defines",
    "W103": "a label that nothing jumps to",
    "W104": "an AUTO or LOCAL variable that the program never uses",
    "W105": "a statement after an unconditional GOTO, RETURN, STOP or HALT that no label reaches",
    "W106": "a string constant over 128 characters (the V+ limit)",
    "W107": "more arguments than the called program's .PROGRAM line declares",
}
"""Each warning's code and what it means."""

MAX_STRING = 128
"""The longest string constant V+ takes: "Strings can contain from 0 to 128 characters" (V+ Language User's
Guide v17, "String Data Type", p. 100)."""

_JUMPS = frozenset({"RETURN", "RETURNE", "STOP", "HALT"})
_ARMS = frozenset({"ELSE", "ANY"})
_CLOSERS = frozenset({"END"})
_WORD = re.compile(r"[$#]?[A-Za-z][A-Za-z0-9._]*")


@dataclass(frozen=True, slots=True)
class Finding:
    """One warning: ``code`` (:data:`CODES`), 1-based ``line``, ``column`` and ``end_column`` (the column after
    the word), ``message`` naming the word and the program."""

    file: str
    line: int
    column: int
    end_column: int
    code: str
    message: str


@dataclass(frozen=True, slots=True)
class Use:
    """Where a program names something: a variable (``name``, ``name[]`` for an array) or a called program."""

    key: str
    line: int
    column: int
    end_column: int
    args: int = 0           # a call's argument count


@dataclass(slots=True)
class Facts:
    """What one program contributes to :func:`warnings`: its global reads and assignments, its calls, and its own
    warnings. ``assigns`` may hold any word of a line that did not parse (what it assigned is not known)."""

    file: str
    program: str
    params: int
    reads: list[Use] = field(default_factory=list)
    assigns: set[str] = field(default_factory=set)
    calls: list[Use] = field(default_factory=list)
    own: list[Finding] = field(default_factory=list)

    def moved(self, lines: int) -> Facts:
        """The same facts ``lines`` lines further down (a program that moved in its file)."""
        if not lines:
            return self
        return Facts(self.file, self.program, self.params,
                     [replace(u, line=u.line + lines) for u in self.reads], self.assigns,
                     [replace(u, line=u.line + lines) for u in self.calls],
                     [replace(f, line=f.line + lines) for f in self.own])


def data_keys(data: Iterable[tuple]) -> set[str]:
    """The variables a module's data sections (``.REALS``, ``.LOCATIONS`` ...) assign: ``(kind, name, index,
    value)`` entries as :class:`~aioadept.vplus.loader.Module` holds them."""
    return {name + ("[]" if index is not None else "") for _, name, index, _ in data}


def warnings(all_facts: Iterable[Facts], assigned: set[str] = frozenset()) -> list[Finding]:
    """The warnings of a set of programs: each program's own, and those across programs; ``assigned``: the
    variables data sections assign (:func:`data_keys`)."""
    all_facts = list(all_facts)
    defined = {f.program: f.params for f in all_facts}
    written = set(assigned).union(*(f.assigns for f in all_facts))
    out: list[Finding] = []
    for f in all_facts:
        out.extend(f.own)
        for u in f.reads:
            if u.key not in written:
                out.append(Finding(f.file, u.line, u.column, u.end_column, "W101",
                                   f"{_shown(u.key)} is read in {f.program} but nothing assigns it in the loaded "
                                   "modules"))
        for u in f.calls:
            if u.key not in defined:
                out.append(Finding(f.file, u.line, u.column, u.end_column, "W102",
                                   f"{f.program} calls {u.key}, which no loaded module defines"))
            elif u.args > defined[u.key]:
                out.append(Finding(f.file, u.line, u.column, u.end_column, "W107",
                                   f"{f.program} calls {u.key} with {u.args} arguments; its .PROGRAM line "
                                   f"declares {defined[u.key]}"))
    return out


def _shown(key: str) -> str:
    return key[:-2] + "[]" if key.endswith("[]") else key


# -- one program ------------------------------------------------------------------------------------------------

def facts(prog: Program) -> Facts:
    """The facts of one loaded program (also of one with lines that did not parse: their words count as
    assigned and used, and the warnings about labels and unreachable lines are left out, since a lost line may
    have been a jump or a label)."""
    out = Facts(prog.file, prog.name, len(prog.params))
    params = {p.name + ("[]" if p.is_array else "") for p in prog.params}
    locals_: dict[str, tuple[int, str]] = {}            # AUTO/LOCAL key -> (line, word)
    for line, st in prog.steps:
        st = st.stmt if isinstance(st, N.Label) else st
        if isinstance(st, N.Declare) and st.word != "GLOBAL":
            for name, _typ, is_arr in st.names:
                if name in params or name + "[]" in params:
                    continue            # an error already (the compiler's)
                locals_.setdefault(name + ("[]" if is_arr else ""), (line, st.word))
    walk = _Walk()
    for line, st in prog.steps:
        walk.stmt(line, st)
    parsed = {line for line, _ in prog.steps}
    lost = {n: code for n, code in prog.source.items() if n not in parsed}
    for code in lost.values():
        for w in _WORD.findall(code):
            walk.writes.add(norm(w))
            walk.writes.add(norm(w) + "[]")
            walk.used.update((norm(w), norm(w) + "[]"))
    scoped = params | set(locals_)
    for u in walk.reads:
        if u.key in scoped:
            if u.key in locals_ and u.key not in walk.writes:
                out.own.append(Finding(prog.file, u.line, u.column, u.end_column, "W101",
                                       f"{_shown(u.key)} ({locals_[u.key][1]}) is read in {prog.name} but "
                                       f"nothing in {prog.name} assigns it"))
        else:
            out.reads.append(u)
    out.assigns = walk.writes - scoped
    for u in walk.calls:
        # the called name's columns: after the instruction (CALL, EXECUTE, REACTE; CALLS "name": in the string)
        col, end = _column(prog, u.line, u.key, after=_WORD.findall(prog.source.get(u.line, ""))[0])
        out.calls.append(replace(u, column=col, end_column=end))
    for key, (line, word) in locals_.items():
        if key not in walk.used:
            col, end = _column(prog, line, key.removesuffix("[]"), after=word)
            out.own.append(Finding(prog.file, line, col, end, "W104",
                                   f"{word} {_shown(key)} is never used in {prog.name}"))
    out.own.extend(Finding(prog.file, line, span.col or 1, span.end or 1, "W106",
                           f"a string constant of {length} characters in {prog.name}: V+ takes at most {MAX_STRING}")
                   for line, span, length in walk.long_strings)
    if not lost:
        out.own.extend(_unused_labels(prog, walk.targets))
        out.own.extend(_unreachable(prog))
    return out


def _column(prog: Program, line: int, word: str, after: str = "") -> tuple[int, int]:
    """The columns of ``word`` (a name, case-insensitive) in the source of ``line``, searched after the word
    ``after``; the line's first column when it is not found."""
    code = prog.source.get(line, "")
    start = code.upper().find(after.upper()) + len(after) if after else 0
    m = re.compile(rf"(?<![A-Za-z0-9._$#]){re.escape(word)}[A-Za-z0-9._]*", re.IGNORECASE).search(code,
                                                                                                    max(start, 0))
    indent = prog.indent.get(line, 0)
    if m is None:
        return indent + 1, indent + 1 + len(code.split(" ")[0])
    return indent + m.start() + 1, indent + m.end() + 1


class _Walk:
    """The variables a program's statements read, assign and mention, its calls and its jump targets."""

    def __init__(self) -> None:
        self.reads: list[Use] = []
        self.writes: set[str] = set()
        self.used: set[str] = set()
        self.calls: list[Use] = []
        self.targets: set[int] = set()
        self.long_strings: list[tuple[int, N.Span, int]] = []
        self.line = 0

    def read(self, e: N.Node | None) -> None:
        """An expression whose variables are read."""
        t = type(e)
        if t is N.Num or t is N.Fmt or e is None:
            return
        if t is N.BinOp:
            self.read(e.left)
            self.read(e.right)
            return
        if t is N.Str:
            if len(e.value) > MAX_STRING and not e.bare:
                self.long_strings.append((self.line, e.span, len(e.value)))
            return
        if isinstance(e, (N.Name, N.Index, N.Array)):
            key = e.name + ("" if isinstance(e, N.Name) else "[]")
            self.used.add(key)
            span = e.span
            self.reads.append(Use(key, span.line or self.line, span.col or 1, span.end or span.col + 1))
            if isinstance(e, N.Index):
                for i in e.index:
                    self.read(i)
            return
        if isinstance(e, N.Call) and e.name in ("DEFINED", "LAST"):
            # asks whether it is defined, or how long it is: not a read of its value
            for a in e.args:
                self.mention(a)
            return
        if isinstance(e, N.Call) and e.name == "$DECODE" and e.args and e.args[0] is not None:
            self.read(e.args[0])        # the string is read, then what is taken off it is removed
            self.write(e.args[0])
            for a in e.args[1:]:
                self.read(a)
            return
        for c in e.children():
            self.read(c)

    def mention(self, e: N.Node | None) -> None:
        if isinstance(e, (N.Name, N.Index, N.Array)):
            self.used.add(e.name + ("" if isinstance(e, N.Name) else "[]"))
            for i in getattr(e, "index", ()):
                self.read(i)
        elif e is not None:
            self.read(e)

    def write(self, e: N.Node | None) -> None:
        """A variable assigned (its index expressions are read)."""
        if isinstance(e, (N.Name, N.Index, N.Array)):
            key = e.name + ("" if isinstance(e, N.Name) else "[]")
            self.writes.add(key)
            self.mention(e)
        else:
            self.read(e)

    def by_ref(self, args: tuple) -> None:
        """CALL arguments: a variable is passed by reference, and the callee may assign it."""
        for a in args:
            if isinstance(a, (N.Name, N.Index, N.Array)):
                self.write(a)
            else:
                self.read(a)

    def stmt(self, line: int, st: N.Stmt) -> None:
        self.line = line
        if isinstance(st, N.Label):
            if st.stmt is not None:
                self.stmt(line, st.stmt)
            return
        handler = getattr(self, "s_" + type(st).__name__, None)
        if handler is not None:
            handler(st)
        else:
            for c in st.children():
                self.read(c)

    def s_Assign(self, st: N.Assign) -> None:
        self.write(st.target)
        self.read(st.value)

    def s_For(self, st: N.For) -> None:
        self.write(st.var)
        for e in (st.start, st.stop, st.step):
            self.read(e)

    def s_Goto(self, st: N.Goto) -> None:
        self.targets.add(st.label)

    def s_IfGoto(self, st: N.IfGoto) -> None:
        self.targets.add(st.label)
        self.read(st.cond)

    def s_Declare(self, st: N.Declare) -> None:
        pass

    def s_CallStmt(self, st: N.CallStmt) -> None:
        self.calls.append(Use(st.name, self.line, 0, 0, len(st.args)))
        self.by_ref(st.args)

    def s_Calls(self, st: N.Calls) -> None:
        if isinstance(st.target, N.Str):
            self.calls.append(Use(norm(st.target.value), self.line, 0, 0, len(st.args)))
        self.read(st.target)
        self.by_ref(st.args)

    def s_Execute(self, st: N.Execute) -> None:
        self.calls.append(Use(st.name, self.line, 0, 0, len(st.args)))
        for e in (st.task, *st.args, *st.extra):
            self.read(e)

    def s_Reacte(self, st: N.Reacte) -> None:
        self.calls.append(Use(st.name, self.line, 0, 0, 0))

    def s_Prompt(self, st: N.Prompt) -> None:
        for e in st.items:
            if isinstance(e, (N.Name, N.Index)):
                self.write(e)
            else:
                self.read(e)

    def s_Read(self, st: N.Read) -> None:
        # READ (lun, handle, mode): the handle variable receives the client's (as the emulator passes it)
        for i, e in enumerate(st.args):
            (self.write if i == 1 else self.read)(e)
        for e in st.targets:
            self.write(e)

    def s_IoStmt(self, st: N.IoStmt) -> None:
        # ATTACH/FOPEN (lun, ...): a variable as the first argument receives the LUN or handle
        for i, e in enumerate(st.args):
            (self.write if i == 0 else self.read)(e)
        for e in st.items:
            self.read(e)

    def s_Here(self, st: N.Here) -> None:
        self.write(st.target)

    def s_Decompose(self, st: N.Decompose) -> None:
        self.write(st.target)
        self.read(st.value)


def _unused_labels(prog: Program, targets: set[int]) -> Iterator[Finding]:
    for line, st in prog.steps:
        if isinstance(st, N.Label) and st.number not in targets:
            col = prog.indent.get(line, 0) + 1
            yield Finding(prog.file, line, col, col + len(str(st.number)), "W103",
                          f"label {st.number} in {prog.name}: nothing jumps to it")


def _unreachable(prog: Program) -> Iterator[Finding]:
    """The first statement of each run of statements after an unconditional jump (GOTO, RETURN, STOP, HALT) in
    the same block, up to a label, the block's next arm (ELSE, VALUE, ANY) or its end."""
    depth = 0
    dead: int | None = None          # the block depth the jump was at, while the lines after it are dead
    reported = False
    jump = (0, "")
    for line, st in prog.steps:
        if isinstance(st, N.Label):
            dead = None
            if st.stmt is None:
                continue
            st = st.stmt
        word = st.word if isinstance(st, N.Word) else ""
        closes = word in _CLOSERS or isinstance(st, N.Until)
        arm = word in _ARMS or isinstance(st, N.Value)
        if dead is not None:
            if (closes or arm) and depth == dead:
                dead = None
            elif not (reported or closes or arm or isinstance(st, N.Nop)):
                col = prog.indent.get(line, 0) + 1
                yield Finding(prog.file, line, col, col + len(prog.source.get(line, " ").split()[0]), "W105",
                              f"unreachable in {prog.name}: nothing reaches this line after the {jump[1]} on "
                              f"line {jump[0]} (no label between)")
                reported = True
        if word == "DO" or isinstance(st, (N.If, N.While, N.For, N.Case)):
            depth += 1
        elif closes:
            depth -= 1
        if dead is None and (isinstance(st, N.Goto) or word in _JUMPS):
            dead, reported, jump = depth, False, (line, "GOTO" if isinstance(st, N.Goto) else word)
