"""V+ programs to Python: each ``.PROGRAM`` becomes one generator function.

Why generate Python source: a tree-walking interpreter in Python runs a simple V+ statement in several
microseconds; generated code runs it as a few bytecodes (a dict store, an ``array('f')`` round trip for REAL
precision). Structured control (IF, WHILE, DO, FOR, CASE) becomes native Python control flow. A program that uses
GOTO is cut into segments at its labels and runs in a small dispatch loop: each body that holds labels (the
program's, or a block's) is one such loop over its segments, and a GOTO raises the label's ``_GOTO[k]``, which
the loop of the body holding label ``k`` catches (the labels of a body are numbered consecutively, so it checks a
range). A GOTO may go to a label of its own body or of any body around it (out of blocks); a GOTO into a block
it is not in is refused at load (docs/vplus.md, "Step labels"). ``EXIT``/``NEXT`` with such a dispatch loop
between them and their loop raise ``_Goto(-1)``/``_Goto(-2)``, which that loop catches.

Generated functions are generators, so that a task can block (WAIT, READ, a motion waiting for its slot) and be
time-sliced: every yield is a wake-up time in runtime seconds, or ``PREEMPT`` (-1.0) when the task has used its
slice. Loop iterations are counted at every loop back-edge and GOTO; each ``_BUDGET`` of them the generated code
asks ``_slice_over()`` whether the slice has ended (virtual time: every time, so a slice is ``BUDGET`` iterations;
real time: when the task has run for 1 ms, :mod:`aioadept.vplus.runtime`, which also ends a slice at a CALL).

Each simple statement sits in ``try/except`` (free in CPython 3.11 unless it raises): an error becomes a V+ error
with the program name and line, and goes to the task's REACTE program if there is one, after which execution
resumes at the next statement (V+ RETURNE semantics).

Variables live in dicts: ``G`` (globals, shared by all tasks), ``L`` (AUTO, per call), ``S`` (LOCAL, per program
and task). A parameter is a ``(container, key)`` pair bound by the caller, so that a variable passed as an argument
is passed by reference and an expression by value. Arrays are dicts ``index -> value`` stored under ``name[]``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

from aioadept.errors import AdeptError
from aioadept.vplus import nodes as N
from aioadept.vplus import registry
from aioadept.vplus.program import LoadProblem, Program
from aioadept.vplus.values import _Goto

BUDGET = 2000
"""Loop iterations a task runs before it yields its time slice (virtual time; the generated code reads the
runtime's ``_BUDGET``, which is smaller in real time, where the slice is measured on the clock)."""

_LOC_FUNCS = registry.of_result("loc")
_PP_FUNCS = registry.of_result("pp")
_STR_FUNCS = registry.of_result("str")
_FMT_RE = re.compile(r"([A-Z])(\d+)?(?:\.(\d+))?\Z")       # as builtins._FMT_RE
_LOOP_JUMP = {"EXIT": _Goto(-1), "NEXT": _Goto(-2)}               # raised across a dispatch loop (module doc)


class CompileError(AdeptError):
    """A program that cannot be compiled: ``line`` (0: the statement's), ``message``, the offending ``word`` and
    the node whose span says where (``None``: the statement)."""

    def __init__(self, line: int, message: str, word: str, node: N.Node | None = None) -> None:
        super().__init__(message)
        self.line, self.message, self.word, self.node = line, message, word, node


@dataclass
class _Block:
    kind: str
    line: int
    head: Any
    body: list = field(default_factory=list)
    orelse: list = field(default_factory=list)        # IF: ELSE part
    cases: list = field(default_factory=list)         # CASE: [(values or None for ANY, body)]
    until: Any = None


def _block_kind(st: N.Stmt) -> str | None:
    """The kind of block a statement opens (IF, WHILE, DO, FOR, CASE), or None."""
    if isinstance(st, N.Word):
        return "DO" if st.word == "DO" else None
    return _BLOCK_OPEN.get(type(st))


_BLOCK_OPEN = {N.If: "IF", N.While: "WHILE", N.For: "FOR", N.Case: "CASE"}


class _Nester:
    """Flat steps to a tree of :class:`_Block` and ``(line, stmt)`` items (:func:`_nest`)."""

    def __init__(self) -> None:
        self.root: list = []
        self.stack: list[tuple[_Block | None, list]] = [(None, self.root)]
        self.problems: list[CompileError] = []

    def fail(self, line: int, message: str, word: str, node: N.Node) -> None:
        """Record a problem; the statement is left out and nesting goes on from the next line."""
        self.problems.append(CompileError(line, message, word, node))

    def step(self, line: int, st: N.Stmt) -> None:
        if isinstance(st, N.Label):
            # in the body open at its line: on an END, ELSE, VALUE or UNTIL line that is the end of that body
            self.stack[-1][1].append((line, N.Label(st.number, None, span=st.span)))
            if st.stmt is None:
                return
            st = st.stmt
        kind = _block_kind(st)
        if kind is not None:
            blk = _Block(kind, line, st)
            self.stack[-1][1].append(blk)
            self.stack.append((blk, blk.body))
        elif isinstance(st, N.Word) and st.word in self._CLOSERS:
            getattr(self, self._CLOSERS[st.word])(line, st)
        elif isinstance(st, N.Value):
            self.case_arm(line, "VALUE", st.values, st)
        elif isinstance(st, N.Until):
            self.until(line, st)
        else:
            self.stack[-1][1].append((line, st))

    _CLOSERS = {"ELSE": "else_", "END": "end", "ANY": "any_"}

    def else_(self, line: int, st: N.Stmt) -> None:
        blk = self.stack[-1][0]
        if blk is None or blk.kind != "IF" or self.stack[-1][1] is blk.orelse:
            self.fail(line, "ELSE without IF", "ELSE", st)
        else:
            self.stack[-1] = (blk, blk.orelse)

    def any_(self, line: int, st: N.Stmt) -> None:
        self.case_arm(line, "ANY", None, st)

    def case_arm(self, line: int, kind: str, values: tuple | None, st: N.Stmt) -> None:
        blk = self.stack[-1][0]
        if blk is None or blk.kind != "CASE":
            self.fail(line, f"{kind} outside CASE", kind, st)
            return
        body: list = []
        blk.cases.append((values, body))
        self.stack[-1] = (blk, body)

    def end(self, line: int, st: N.Stmt) -> None:
        blk = self.stack[-1][0]
        if blk is None:
            self.fail(line, "END without an open block", "END", st)
            return
        if blk.kind == "DO":
            self.fail(line, "DO closed by END instead of UNTIL", "END", st)
        self.stack.pop()

    def until(self, line: int, st: N.Until) -> None:
        blk = self.stack[-1][0]
        if blk is None or blk.kind != "DO":
            self.fail(line, "UNTIL without DO", "UNTIL", st)
            return
        blk.until = st.cond
        self.stack.pop()

    def close(self) -> list:
        for blk, _ in reversed(self.stack[1:]):
            self.fail(blk.line, f"{blk.kind} not closed", blk.kind, blk.head)
        return self.root


def _nest(steps: list[tuple[int, Any]]) -> tuple[list, list[CompileError]]:
    """Flat steps to a tree of :class:`_Block` and ``(line, stmt)`` items, and the problems of the nesting."""
    nester = _Nester()
    for line, st in steps:
        nester.step(line, st)
    return nester.close(), nester.problems


class _Gen:
    def __init__(self, prog: Program, doubles: set[str], boxed: frozenset[str] = frozenset(),
                 traced: bool = False, variables: bool = True) -> None:
        self.prog = prog
        self.traced = traced                # the instrumented form: a line hook before each statement
        self.variables = variables          # traced: every AUTO in L, where a debugger reads and sets it
        self.at_line = 0                    # the V+ line of the code being emitted (traced: the hook's)
        self.line_of: list[int] = []        # traced: the V+ line of each emitted Python line
        self.keep_boxed = boxed             # AUTOs that stay in L (passed on by reference: known from a former pass)
        self.fast: set[str] = set()         # AUTO scalars that are Python locals of the generated function
        self.boxed: set[str] = set()        # AUTOs found passed on by reference in this pass
        self.doubles = set(doubles)
        self.autos: dict[str, str] = {}
        self.statics: dict[str, str] = {}
        self.params: dict[str, tuple[int, bool]] = {p.name: (i, p.is_array) for i, p in enumerate(prog.params)}
        self.lines: list[str] = []
        self.ind = 2
        self.n = 0
        self.consts: list[Any] = []
        self.loops: list[str] = []          # kinds of enclosing loops, for EXIT/NEXT
        self.labels: dict[int, int] = {}    # label -> its GOTO index (1, 2, ...; a body's consecutive)
        self.label_body: dict[int, int] = {}    # label -> id() of the body (list of items) that holds it
        self.bodies: list[int] = []         # id() of the bodies around the code being emitted
        self.frames: list[str] = []         # "loop" and "dispatch" around it, innermost last (EXIT/NEXT)
        self.problems: list[CompileError] = []

    # -- output ---------------------------------------------------------------------------------------------
    def emit(self, s: str) -> None:
        for ln in s.split("\n"):
            self.lines.append("    " * self.ind + ln)
            self.line_of.append(self.at_line)

    def hook(self, line: int) -> None:
        """Traced form only: the line hook before the statement of V+ line ``line`` (runtime.Runtime.set_tracer):
        it runs when the task is traced or the line is one the tracer asked for (``_BP``, a set per program)."""
        if self.traced:
            self.at_line = line
            self.emit(f"if T.trace or {line} in _BP: yield from _dbg(T, {line})")

    def tmp(self, p: str = "_t") -> str:
        self.n += 1
        return f"{p}{self.n}"

    def const(self, v: Any) -> str:
        self.consts.append(v)
        return f"_K[{len(self.consts) - 1}]"

    # -- names ----------------------------------------------------------------------------------------------
    def scope(self, name: str) -> tuple[str, str]:
        """(container code, key code) of a scalar variable that is passed on by reference (an argument of CALL,
        the string of $DECODE, an I/O handle, DEFINED): an AUTO used so stays in ``L`` (see :func:`compile_program`)."""
        if name in self.fast:
            self.boxed.add(name)
        if name in self.params:
            i, is_arr = self.params[name]
            if is_arr:
                raise CompileError(0, f"{name} is an array parameter", name)
            return f"P{i}c", f"P{i}k"
        if name in self.autos:
            return "L", repr(name)
        if name in self.statics:
            return "S", repr(name)
        return "G", repr(name)

    def lv(self, name: str) -> str:
        """Code of a scalar variable as a Python expression and assignment target."""
        if name in self.fast:
            return _local(name)
        if name in self.params:
            i, is_arr = self.params[name]
            if is_arr:
                raise CompileError(0, f"{name} is an array parameter", name)
            return f"P{i}c[P{i}k]"
        c, key = self.scope(name)
        return f"{c}[{key}]"

    def arr(self, name: str, write: bool) -> str:
        """Code of the dict of an array (created on first write)."""
        if name in self.params:
            i, is_arr = self.params[name]
            if not is_arr:
                raise CompileError(0, f"{name} is not an array parameter", name)
            return f"A{i}"
        c = "L" if name in self.autos else ("S" if name in self.statics else "G")
        key = repr(name + "[]")
        return f"({c}.get({key}) or _arr({c}, {key}))" if write else f"{c}[{key}]"

    def index(self, idx: tuple) -> str:
        parts = []
        for e in idx:
            if isinstance(e, N.Num) and e.value >= 0:
                # rounded, not truncated (V+ Language User's Guide v17, p. 102), as builtins.vint does at run time
                parts.append(repr(int(math.floor(e.value + 0.5))))
            else:
                parts.append(f"_IX[{self.val(e)[0]}]")     # a dict of 0.0..4095.0; _ix() for the rest
        return parts[0] if len(parts) == 1 else "(" + ", ".join(parts) + ")"

    def is_double(self, name: str) -> bool:
        if name in self.autos:
            return self.autos[name] == "DOUBLE"
        if name in self.statics:
            return self.statics[name] == "DOUBLE"
        return name in self.doubles

    # -- expressions: (code, type) with type num|str|loc|pp|any ----------------------------------------------
    def val(self, e: N.Expr) -> tuple[str, str]:
        """The code of expression ``e`` and its type; a problem names the sub-expression's node."""
        try:
            return getattr(self, "val_" + type(e).__name__)(e)
        except CompileError as exc:
            if exc.node is None:
                exc.node = e
            raise

    def val_Num(self, e: N.Num) -> tuple[str, str]:
        return repr(float(e.value)), "num"

    def val_Str(self, e: N.Str) -> tuple[str, str]:
        return repr(e.value), "str"

    def val_Name(self, e: N.Name) -> tuple[str, str]:
        return self.lv(e.name), self.vtype(e.name)

    def val_Paren(self, e: N.Paren) -> tuple[str, str]:
        return self.val(e.expr)             # (x) as a CALL argument: its value (passed by value)

    def val_Index(self, e: N.Index) -> tuple[str, str]:
        return f"{self.arr(e.name, False)}[{self.index(e.index)}]", self.vtype(e.name)

    def val_Array(self, e: N.Array) -> tuple[str, str]:
        raise CompileError(0, "an array (name[]) is not a value here", e.name + "[]")

    def val_Fmt(self, e: N.Fmt) -> tuple[str, str]:
        raise CompileError(0, "a format is not a value here", "/" + e.spec)

    def val_Unary(self, e: N.Unary) -> tuple[str, str]:
        if e.op == "-":
            return f"(-{self.val(e.operand)[0]})", "num"
        if e.op == "NOT":
            return f"(0.0 if {self.cond(e.operand)} else -1.0)", "num"
        return f"float(~int({self.val(e.operand)[0]}))", "num"

    def val_Shift(self, e: N.Shift) -> tuple[str, str]:
        d = ["0.0" if x is None else self.val(x)[0] for x in e.deltas]
        return f"{_fname('SHIFT')}({self.val(e.base)[0]}, {', '.join(d)})", "loc"

    def vtype(self, name: str) -> str:
        return "str" if name.startswith("$") else ("pp" if name.startswith("#") else "any")

    def val_BinOp(self, e: N.BinOp) -> tuple[str, str]:
        op, a, b = e.op, e.left, e.right
        if op in ("AND", "OR", "XOR", "==", "<>", "<", ">", "<=", ">="):
            return f"(-1.0 if {self.cond(e)} else 0.0)", "num"
        if op == ":":
            return f"_compose({self.val(a)[0]}, {self.val(b)[0]})", "loc"
        ca, ta = self.val(a)
        cb, tb = self.val(b)
        if op == "+":
            t = "str" if "str" in (ta, tb) else "num"
            return f"({ca} + {cb})", t
        if op in ("-", "*", "/"):
            return f"({ca} {op} {cb})", "num"
        if op == "MOD":
            return f"_fmod({ca}, {cb})", "num"
        if op == "^":
            return f"({ca} ** {cb})", "num"
        pyop = {"BAND": "&", "BOR": "|", "BXOR": "^"}[op]
        return f"float(int({ca}) {pyop} int({cb}))", "num"

    def cond(self, e: N.Expr) -> str:
        """Python boolean expression for a V+ condition (non-zero is TRUE)."""
        if isinstance(e, N.BinOp):
            op = e.op
            if op == "AND":
                return f"({self.cond(e.left)} and {self.cond(e.right)})"
            if op == "OR":
                return f"({self.cond(e.left)} or {self.cond(e.right)})"
            if op == "XOR":
                return f"(bool({self.cond(e.left)}) != bool({self.cond(e.right)}))"
            if op in ("==", "<>", "<", ">", "<=", ">="):
                return self.compare(e)
        if isinstance(e, N.Unary) and e.op == "NOT":
            return f"(not {self.cond(e.operand)})"
        return f"({self.val(e)[0]} != 0)"

    def compare(self, e: N.BinOp) -> str:
        pyop = "!=" if e.op == "<>" else e.op
        ca, ta = self.val(e.left)
        cb, tb = self.val(e.right)
        if ("str" in (ta, tb)) and ta != tb and "any" not in (ta, tb):
            raise CompileError(0, "comparison of a string with a number", e.op, e)
        return f"({ca} {pyop} {cb})"

    def val_Call(self, e: N.Call) -> tuple[str, str]:
        name, args = e.name, e.args
        special = _SPECIAL_CALLS.get(name)
        if special is not None:
            return getattr(self, special)(e)
        vals = ", ".join("None" if a is None else self.val(a)[0] for a in args)
        if name in ("IOSTAT", "ERROR", "TASK", "INRANGE", "HERE", "#HERE", "SPEED", "GETC"):
            vals = "T" + (", " + vals if vals else "")
        typ = "loc" if name in _LOC_FUNCS else ("pp" if name in _PP_FUNCS else
                                                ("str" if name in _STR_FUNCS else "num"))
        if name == "GETC":          # may wait for input: the task yields meanwhile (iodev.getc)
            return f"(yield from {_fname(name)}({vals}))", typ
        return f"{_fname(name)}({vals})", typ

    def call_decode(self, e: N.Call) -> tuple[str, str]:
        args = e.args
        if len(args) != 3 or args[0] is None or not isinstance(args[0], (N.Name, N.Index)):
            raise CompileError(0, "$DECODE needs a string variable, breaks and a mode", e.name)
        c, key = self.ref(args[0])
        return f"_decode({c}, {key}, {self.val(args[1])[0]}, {self.val(args[2])[0]})", "str"

    def call_encode(self, e: N.Call) -> tuple[str, str]:
        return self.encode(e.args), "str"

    def call_defined(self, e: N.Call) -> tuple[str, str]:
        if len(e.args) != 1 or e.args[0] is None:
            raise CompileError(0, "DEFINED needs one variable", e.name)
        a = e.args[0]
        if isinstance(a, N.Name):
            c, key = self.scope(a.name)
            if a.name in self.params:
                # a parameter's container is a dict, or the one-element list of a value passed by value
                return f"_defref({c}, {key})", "num"
            return f"(-1.0 if {key} in {c} else 0.0)", "num"
        if isinstance(a, N.Array):
            return f"_defarr(lambda: {self.arr(a.name, False)})", "num"
        if isinstance(a, N.Index):
            return f"_defined(lambda: {self.val(a)[0]})", "num"
        raise CompileError(0, "DEFINED needs a variable", e.name)

    def call_last(self, e: N.Call) -> tuple[str, str]:
        if len(e.args) != 1 or e.args[0] is None or not isinstance(e.args[0], N.Array):
            raise CompileError(0, "LAST needs an array: LAST(a[])", e.name)
        return f"_last(lambda: {self.arr(e.args[0].name, False)})", "num"

    def call_len(self, e: N.Call) -> tuple[str, str]:
        return f"float(len({self.val(e.args[0])[0]}))", "num"

    def encode(self, args: tuple) -> str:
        """$ENCODE with its formats applied at compile time (they are constants): each number goes through
        ``_encv`` with its format, strings are joined as they are. A format the emulator does not know takes
        the general path (``_encode``), which reports it when the line runs."""
        parts: list[str] = []
        spec: tuple = ("D", None, None)
        for a in args:
            if a is None:
                continue
            if isinstance(a, N.Fmt):
                f = a.spec
                m = _FMT_RE.match(f)
                kind = m.group(1) if m else f[:1]
                num = int(m.group(2)) if m and m.group(2) else None
                prec = int(m.group(3)) if m and m.group(3) else None
                if kind == "X":
                    parts.append(repr(" " * (num if num is not None else 1)))
                elif kind == "C":
                    parts.append(repr("\r\n" * (num if num is not None else 1)))
                elif kind in ("S", "N", "B", "U"):
                    pass
                elif kind in ("F", "E", "G", "I", "H", "O", "D"):
                    spec = (kind, num, prec)
                else:
                    return f"_encode(({self.items(args)}))"
                continue
            code, typ = self.val(a)
            if typ == "str":
                parts.append(code)
            elif spec[0] == "F" and not spec[1]:
                # /F0.3 (no width): "%.3f" at once for a REAL, the general _encv for anything else
                pat = "%.{}f".format(spec[2] if spec[2] is not None else 2)
                parts.append(f"({pat!r} % _v if type(_v := {code}) is float else _encv(_v, {self.const(spec)}))")
            else:
                parts.append(f"_encv({code}, {self.const(spec)})")
        if not parts:
            return "''"
        return f"_str({' + '.join(parts)})" if len(parts) > 1 else f"_str({parts[0]})"

    def items(self, args: tuple) -> str:
        """Output items (formats and values) as a tuple body for _encode/_type/_write."""
        out = []
        for a in args:
            if a is None:
                continue
            if isinstance(a, N.Fmt):
                out.append(self.const(("fmt", a.spec)))
            else:
                out.append(self.val(a)[0])
        return ", ".join(out) + ("," if len(out) == 1 else "")

    def ref(self, e: N.Expr) -> tuple[str, str]:
        """(container, key) of an assignable variable or array element."""
        if isinstance(e, N.Name):
            return self.scope(e.name)
        if isinstance(e, N.Index):
            return self.arr(e.name, True), self.index(e.index)
        raise CompileError(0, "expected a variable", _word(e), e)

    def store(self, target: N.Expr, code: str, typ: str, force_loc: bool = False) -> str:
        """A Python statement storing ``code`` into the V+ variable ``target``."""
        t = self.target(target)
        name = target.name
        if name.startswith("$"):
            # _str's checks inline: most stores are short strings
            return f"{t} = _t if type(_t := {code}) is str and len(_t) <= 128 else _str(_t)"
        if name.startswith("#"):
            return f"{t} = _pp({code})"
        if force_loc or typ == "loc":
            if isinstance(target, N.Index):
                # an array holds one type (V+ Language User's Guide v17, p. 105): a location array is a _LocArray
                c, key = ("L", repr(name + "[]")) if name in self.autos else (
                    ("S", repr(name + "[]")) if name in self.statics else ("G", repr(name + "[]")))
                arr = self.arr(name, False) if name in self.params else "None"
                return f"_loc_store({c}, {key}, {arr}, {self.index(target.index)}, _loc({code}), {name!r})"
            return f"{t} = _loc({code})"
        if self.is_double(name):
            return f"{t} = _dbl({code})"
        if typ == "num":
            return f"_F[0] = {code}; {t} = _F[0]"
        return f"_t = {code}\nif type(_t) is float: _F[0] = _t; {t} = _F[0]\nelse: {t} = _real(_t)"

    def target(self, e: N.Expr) -> str:
        """Code of an assignable variable or array element (assigned in the generated code itself)."""
        if isinstance(e, N.Name):
            return self.lv(e.name)
        if isinstance(e, N.Index):
            return f"{self.arr(e.name, True)}[{self.index(e.index)}]"
        raise CompileError(0, "expected a variable", _word(e), e)

    # -- statements -----------------------------------------------------------------------------------------
    def declare(self, steps) -> None:
        executable = False
        for line, st in steps:
            if isinstance(st, N.Label):
                if st.stmt is None:
                    continue
                st = st.stmt
            if isinstance(st, N.Declare):
                if executable:
                    # V+ Language User's Guide v17, p. 36 ("Program Organization")
                    self.problems.append(CompileError(
                        line, f"{st.word} after an executable instruction (AUTO, LOCAL and GLOBAL must precede "
                              "every executable instruction)", st.word, st))
                self.declare_names(line, st)
            elif not isinstance(st, N.Nop):
                executable = True

    def declare_names(self, line: int, st: N.Declare) -> None:
        for name, typ, _ in st.names:
            if st.word == "GLOBAL":
                if typ == "DOUBLE":
                    self.doubles.add(name)
            elif name in self.params:
                self.problems.append(CompileError(line, f"{name} is a parameter", name, st))
            else:
                (self.autos if st.word == "AUTO" else self.statics)[name] = typ

    def program(self) -> str:
        p = self.prog
        tree, self.problems = _nest(p.steps)
        self.declare(p.steps)
        # traced for a debugger: every AUTO stays in L, where it reads and sets them
        self.fast = set() if self.traced and self.variables else {n for n in self.autos if n not in self.keep_boxed}
        self.ind = 0
        self.emit("def _prog(T, A):")
        self.ind = 1
        self.emit("G = _G; _F = _FB")
        self.emit("L = {}")
        if self.statics:
            self.emit(f"S = _static(T, {p.name!r})")
        if self.params:
            self.emit("_nA = len(A)")
        for name, (i, is_arr) in self.params.items():
            if is_arr:
                self.emit(f"A{i} = _argarr(A, {i}, {name!r})")
            else:
                # _arg's checks inline for the usual case (a (container, key) pair, not omitted)
                self.emit(f"P{i}c, P{i}k = _a if (_nA > {i} and type(_a := A[{i}]) is tuple and _a[0] is not _MC) "
                          f"else _arg(A, {i}, {name!r})")
        self.emit("_b = _BUDGET")
        if _uses_goto(p.steps):
            self.number_labels(tree)
            self.body(tree)
        else:
            self.block(tree)
        self.emit("return")
        self.emit("yield")
        return "\n".join(self.lines)

    def number_labels(self, items: list) -> None:
        """Number the labels of a body and then of the bodies in it, so that each body's are consecutive."""
        for line, st in (it for it in items if isinstance(it, tuple) and isinstance(it[1], N.Label)):
            if st.number in self.labels:
                self.problems.append(CompileError(line, f"label {st.number} is defined twice", str(st.number), st))
                continue
            self.labels[st.number] = len(self.labels) + 1
            self.label_body[st.number] = id(items)
        for it in items:
            if isinstance(it, _Block):
                for sub in (it.body, it.orelse, *(body for _, body in it.cases)):
                    self.number_labels(sub)

    def body(self, items: list) -> None:
        """The statements of the program or of a block: a dispatch loop over its segments if labels are in it."""
        self.bodies.append(id(items))
        if any(isinstance(it, tuple) and isinstance(it[1], N.Label) for it in items):
            self.segments(items)
        else:
            self.block(items)
        self.bodies.pop()

    def segments(self, items: list) -> None:
        """A body cut at its labels, run by a dispatch loop that catches the GOTOs to them (the module doc)."""
        segs: list[list] = [[]]
        starts: list[int] = []
        for it in items:
            if isinstance(it, tuple) and isinstance(it[1], N.Label) and it[1].number in self.labels:
                starts.append(self.labels[it[1].number])
                segs.append([])
            else:
                segs[-1].append(it)
        top = len(self.bodies) == 1
        pc = "_pc" if top else self.tmp("_pc")
        self.emit(f"{pc} = {starts[0] - 1}")
        self.emit("while True:")
        self.ind += 1
        self.emit("try:")
        self.ind += 1
        self.frames.append("dispatch")
        for k, seg in zip([starts[0] - 1, *starts], segs, strict=True):
            self.emit(f"if {pc} <= {k}:")
            self.ind += 1
            self.emit("pass")
            self.block(seg)
            self.ind -= 1
        self.frames.pop()
        self.emit("break")
        self.ind -= 1
        self.emit("except _Goto as _g:")
        self.ind += 1
        if not top:                         # a GOTO out of this body (or an EXIT/NEXT) goes on outwards
            self.emit(f"if not {starts[0]} <= _g.pc <= {starts[-1]}: raise")
        self.emit(f"{pc} = _g.pc")
        self.budget()
        self.ind -= 2

    def loop_body(self, kind: str, items: list) -> None:
        """The body of a WHILE, DO or FOR (inside its Python loop): where labels in it may put a dispatch loop
        between an EXIT/NEXT and this loop, the EXIT/NEXT raised across it is caught here."""
        self.loops.append(kind)
        self.frames.append("loop")
        if not _has_label(items):
            self.body(items)
        else:
            self.emit("try:")
            self.ind += 1
            self.body(items)
            self.ind -= 1
            self.emit("except _Goto as _j:")
            self.emit("    if _j.pc == -1: break")
            self.emit("    if _j.pc != -2: raise")
        self.frames.pop()
        self.loops.pop()

    def budget(self) -> None:
        self.emit("_b -= 1")
        self.emit("if not _b:")
        self.emit("    _b = _BUDGET")
        self.emit("    if _slice_over(): yield -1.0")

    def block(self, items: list) -> None:
        if not items:
            self.emit("pass")
        for it in items:
            if isinstance(it, _Block):
                try:
                    self.compound(it)
                except CompileError as exc:
                    self.problems.append(CompileError(exc.line or it.line, exc.message, exc.word,
                                                      exc.node or it.head))
            else:
                line, st = it
                if isinstance(st, (N.Declare, N.Nop, N.Label)):
                    continue
                self.hook(line)
                try:
                    self.visit(line, st)
                except CompileError as exc:
                    self.problems.append(CompileError(line, exc.message, exc.word, exc.node or st))

    def visit(self, line: int, st: N.Stmt) -> None:
        """Generate the code of a simple statement: ``visit_<node class>``."""
        method = getattr(self, "visit_" + type(st).__name__, None)
        if method is None:
            kind = getattr(st, "word", type(st).__name__.upper())
            raise CompileError(line, f"instruction {kind} is not implemented by the emulator", kind, st)
        method(line, st)

    def guarded(self, line: int, code_lines: list[str]) -> None:
        self.emit("try:")
        for c in code_lines:
            self.emit("\n".join("    " + ln for ln in c.split("\n")))
        self.emit("except Exception as _e:")
        self.emit(f"    yield from _err(T, _e, {self.prog.name!r}, {line})")

    def guarded_cond(self, line: int, e: N.Expr) -> str:
        try:
            c = self.cond(e)
        except CompileError as exc:
            self.problems.append(CompileError(line, exc.message, exc.word, exc.node))
            c = "False"
        v = self.tmp("_c")
        self.emit("try:")
        self.emit(f"    {v} = {c}")
        self.emit("except Exception as _e:")
        self.emit(f"    yield from _err(T, _e, {self.prog.name!r}, {line}); {v} = False")
        return v

    def compound(self, b: _Block) -> None:
        getattr(self, "block_" + b.kind)(b)

    def block_IF(self, b: _Block) -> None:
        self.hook(b.line)
        c = self.guarded_cond(b.line, b.head.cond)
        self.emit(f"if {c}:")
        self.ind += 1
        self.body(b.body)
        self.ind -= 1
        if b.orelse:
            self.emit("else:")
            self.ind += 1
            self.body(b.orelse)
            self.ind -= 1

    def block_WHILE(self, b: _Block) -> None:
        self.emit("while True:")
        self.ind += 1
        self.hook(b.line)
        c = self.guarded_cond(b.line, b.head.cond)
        self.emit(f"if not {c}: break")
        self.loop_body("WHILE", b.body)
        self.budget()
        self.ind -= 1

    def block_DO(self, b: _Block) -> None:
        if _direct_next(b.body):
            raise CompileError(b.line, "NEXT inside DO ... UNTIL is not supported by the emulator", "NEXT", b.head)
        self.emit("while True:")
        self.ind += 1
        self.loop_body("DO", b.body)
        self.budget()
        c = self.guarded_cond(b.line, b.until)
        self.emit(f"if {c}: break")
        self.ind -= 1

    def block_CASE(self, b: _Block) -> None:
        v = self.tmp("_v")
        try:
            code = self.val(b.head.expr)[0]
            vals = [[self.val(x)[0] for x in vs] if vs is not None else None for vs, _ in b.cases]
        except CompileError as exc:
            raise CompileError(b.line, exc.message, exc.word, exc.node) from None
        self.hook(b.line)
        self.guarded(b.line, [f"{v} = {code}"])
        first = True
        for (vs, body), codes in zip(b.cases, vals, strict=True):
            if vs is None:
                self.emit("else:" if not first else "if True:")
            else:
                test = " or ".join(f"{v} == {c}" for c in codes)
                self.emit(("if " if first else "elif ") + test + ":")
            first = False
            self.ind += 1
            self.body(body)
            self.ind -= 1

    def block_FOR(self, b: _Block) -> None:
        var, start, end, step = b.head.var, b.head.start, b.head.stop, b.head.step
        try:
            v = self.target(var)
            scode = self.val(start)[0]
            ecode = self.val(end)[0]
            stcode = "1.0" if step is None else self.val(step)[0]
        except CompileError as exc:
            raise CompileError(b.line, exc.message, exc.word, exc.node) from None
        e, s = self.tmp("_e"), self.tmp("_s")
        dbl = self.is_double(var.name)
        conv = "_dbl" if dbl else "_f32"
        self.hook(b.line)
        self.guarded(b.line, [f"{e} = float({ecode}); {s} = float({stcode})", f"{v} = {conv}({scode})"])
        const_pos = step is None or (isinstance(step, N.Num) and step.value > 0)
        test = f"{v} <= {e}" if const_pos else f"({v} <= {e} if {s} > 0 else {v} >= {e})"
        if dbl:
            inc = f"{v} = {v} + {s}"
        else:
            inc = f"_F[0] = {v} + {s}; {v} = _F[0]"
        if _direct_next(b.body):
            f = self.tmp("_first")
            self.emit(f"{f} = True")
            self.emit("while True:")
            self.ind += 1
            self.emit(f"if not {f}: {inc}")
            self.emit(f"{f} = False")
            self.emit(f"if not ({test}): break")
            self.loop_body("FOR", b.body)
            self.budget()
            self.ind -= 1
        else:
            self.emit(f"while {test}:")
            self.ind += 1
            self.loop_body("FOR", b.body)
            self.budget()
            self.emit(inc)
            self.ind -= 1

    # -- simple statements: one visit method per node class ---------------------------------------------------
    def visit_Assign(self, line: int, st: N.Assign) -> None:
        code, typ = self.val(st.value)
        target = st.target
        if isinstance(target, N.Array):
            raise CompileError(line, "cannot assign to a whole array", target.name, target)
        if not st.is_set and (typ in ("loc", "pp") or target.name.startswith("#")):
            # V+ Language User's Guide v17, p. 111 ("Assignment Operator")
            raise CompileError(line, "a location is assigned with SET (SET name = value)", target.name, target)
        force = st.is_set and not target.name.startswith(("$", "#"))
        self.guarded(line, [self.store(target, code, typ, force)])

    def goto_index(self, line: int, label: int, st: N.Stmt) -> int:
        if label not in self.labels:
            raise CompileError(line, f"GOTO to an undefined label {label}", str(label), st)
        if self.label_body[label] not in self.bodies:
            # V+'s rule for a jump into a block is not in the manuals we have: refused, the safe side
            raise CompileError(line, f"GOTO {label} into a block (IF, CASE, WHILE, DO or FOR) the GOTO is not in is "
                                     "not supported by the emulator", str(label), st)
        return self.labels[label]

    def visit_Goto(self, line: int, st: N.Goto) -> None:
        self.emit(f"raise _GOTO[{self.goto_index(line, st.label, st)}]")

    def visit_IfGoto(self, line: int, st: N.IfGoto) -> None:
        k = self.goto_index(line, st.label, st)
        c = self.guarded_cond(line, st.cond)
        self.emit(f"if {c}: raise _GOTO[{k}]")

    def visit_Word(self, line: int, st: N.Word) -> None:
        """RETURN, RETURNE, HALT, STOP, PAUSE, BREAK, BRAKE, NULL."""
        name = self.prog.name
        if st.word in ("RETURN", "RETURNE"):
            self.emit("return")
            return
        code = {"HALT": f"_halt(T, {name!r}, {line})", "STOP": "_stop(T)",
                "PAUSE": f"yield from _pause(T, {name!r}, {line})", "BREAK": "yield from _robot(T, 'BREAK')",
                "BRAKE": "_brake(T)", "NULL": None}
        if st.word not in code:
            raise CompileError(line, f"instruction {st.word} is not implemented by the emulator", st.word, st)
        if code[st.word] is not None:
            self.guarded(line, [code[st.word]])

    def visit_LoopJump(self, line: int, st: N.LoopJump) -> None:
        k = st.word
        if not self.loops:
            raise CompileError(line, f"{k} outside a loop", k, st)
        if st.count != 1:
            raise CompileError(line, f"{k} with a count is not supported by the emulator", k, st)
        if self.frames[-1] == "dispatch":
            self.emit(f"raise {self.const(_LOOP_JUMP[k])}")
        else:
            self.emit("break" if k == "EXIT" else "continue")

    def visit_CallStmt(self, line: int, st: N.CallStmt) -> None:
        args = self.call_args(st.args)
        self.guarded(line, [f"yield from _call(T, {st.name!r}, ({args}))"])

    def visit_Calls(self, line: int, st: N.Calls) -> None:
        args = self.call_args(st.args)
        self.guarded(line, [f"yield from _call(T, _progname({self.val(st.target)[0]}), ({args}))"])

    def visit_Wait(self, line: int, st: N.Wait) -> None:
        if st.cond is None:
            self.guarded(line, ["yield _tick()"])
        else:
            c = self.cond(st.cond)
            self.guarded(line, [f"while not {c}:", "    yield _ctick(T)"])

    def visit_Type(self, line: int, st: N.Type) -> None:
        self.guarded(line, [f"_type(T, ({self.items(st.items)}))"])

    def visit_Prompt(self, line: int, st: N.Prompt) -> None:
        items = [x for x in st.items if x is not None]
        targets = [x for x in items if isinstance(x, (N.Name, N.Index))]
        texts = [x for x in items if not isinstance(x, (N.Name, N.Index))]
        lines = [f"_type(T, ({self.items(texts)} {self.const(('fmt', 'S'))},))"]
        for t in targets:
            v = self.tmp("_in")
            lines.append(f"{v} = yield from _prompt(T, {t.name.startswith('$')!r})")
            lines.append(self.store(t, v, "str" if t.name.startswith("$") else "num"))
        self.guarded(line, lines)

    def visit_Signal(self, line: int, st: N.Signal) -> None:
        vals = ", ".join(self.val(e)[0] for e in st.items)
        self.guarded(line, [f"_signal(T, ({vals},))"])

    def visit_Event(self, line: int, st: N.Event) -> None:
        vals = ", ".join("None" if e is None else self.val(e)[0] for e in st.items)
        call = "yield from _wait_event" if st.word == "WAIT.EVENT" else "_set_event"
        self.guarded(line, [f"{call}(T, ({vals}{',' if vals else ''}))"])

    def visit_IoStmt(self, line: int, st: N.IoStmt) -> None:
        refs = []
        for i, a in enumerate(st.args):
            if a is None:
                refs.append("None")
            elif i == 0 and isinstance(a, (N.Name, N.Index)):
                c, key = self.ref(a)
                refs.append(f"({c}, {key})")
            else:
                refs.append(f"(None, {self.val(a)[0]})")
        text = self.items(st.items) if st.items else ""
        self.guarded(line, [f"yield from _io_{st.word.lower()}(T, ({', '.join(refs)}{',' if len(refs) == 1 else ''}), "
                            f"({text}))"])

    def visit_Read(self, line: int, st: N.Read) -> None:
        args = st.args
        lun = self.val(args[0])[0] if args and args[0] is not None else "None"
        handle = "None"
        if len(args) > 1 and args[1] is not None:
            if not isinstance(args[1], (N.Name, N.Index)):
                raise CompileError(line, "READ handle must be a variable", "READ", args[1])
            c, key = self.ref(args[1])
            handle = f"({c}, {key})"
        mode = self.val(args[2])[0] if len(args) > 2 and args[2] is not None else "0.0"
        tgts = ", ".join("({}, {})".format(*self.ref(t)) for t in st.targets)
        comma = "," if len(st.targets) == 1 else ""
        self.guarded(line, [f"yield from _io_read(T, {lun}, {handle}, {mode}, ({tgts}{comma}))"])

    def visit_Write(self, line: int, st: N.Write) -> None:
        args = st.args
        lun = self.val(args[0])[0] if args and args[0] is not None else "None"
        handle = self.val(args[1])[0] if len(args) > 1 and args[1] is not None else "None"
        self.guarded(line, [f"yield from _io_write(T, {lun}, {handle}, ({self.items(st.items)}))"])

    def visit_Execute(self, line: int, st: N.Execute) -> None:
        tcode = self.val(st.task)[0] if st.task is not None else "None"
        vals = ", ".join("None" if a is None else self.val(a)[0] for a in st.args)
        comma = "," if len(st.args) == 1 else ""
        self.guarded(line, [f"_execute(T, {tcode}, {st.name!r}, ({vals}{comma}))"])

    def visit_TaskControl(self, line: int, st: N.TaskControl) -> None:
        vals = ", ".join(self.val(e)[0] for e in st.items)
        fn = {"ABORT": "_abort", "KILL": "_kill", "CYCLE.END": "_cycle_end"}[st.word]
        self.guarded(line, [f"{fn}(T, ({vals}{',' if len(st.items) == 1 else ''}))"])

    def visit_Reacte(self, line: int, st: N.Reacte) -> None:
        self.guarded(line, [f"_reacte(T, {st.name!r})"])

    def visit_Robot(self, line: int, st: N.Robot) -> None:
        if st.word == "TOOL":
            self.guarded(line, [f"_tool(T, {self.val(st.loc)[0]})"])
        elif st.arg is None:
            self.guarded(line, [f"yield from _robot(T, {st.word!r}, {self.val(st.loc)[0]})"])
        else:
            self.guarded(line, [f"yield from _robot(T, {st.word!r}, {self.val(st.loc)[0]}, {self.val(st.arg)[0]})"])

    def visit_Duration(self, line: int, st: N.Duration) -> None:
        self.guarded(line, [f"_duration(T, {self.val(st.time)[0]}, {st.always!r})"])

    def visit_Config(self, line: int, st: N.Config) -> None:
        self.guarded(line, [f"_config(T, {st.word!r})"])

    def visit_DiskOpen(self, line: int, st: N.DiskOpen) -> None:
        if len(st.args) != 1 or st.args[0] is None:
            raise CompileError(line, f"{st.word} needs (lun)", st.word, st)
        self.guarded(line, [f"_disk_open(T, {st.word!r}, {self.val(st.args[0])[0]}, ({self.items(st.items)}))"])

    def visit_Speed(self, line: int, st: N.Speed) -> None:
        self.guarded(line, [f"_speed(T, {self.val(st.speed)[0]}, {st.mode!r})"])

    def visit_Accel(self, line: int, st: N.Accel) -> None:
        vals = ", ".join(self.val(e)[0] for e in st.items)
        self.guarded(line, [f"_accel(T, ({vals},))"])

    def visit_Here(self, line: int, st: N.Here) -> None:
        tgt = st.target
        pp = tgt.name.startswith("#")
        fn = f"{_fname('#HERE')}(T)" if pp else f"{_fname('HERE')}(T)"
        self.guarded(line, [self.store(tgt, fn, "pp" if pp else "loc")])

    def visit_Decompose(self, line: int, st: N.Decompose) -> None:
        tgt = st.target
        if isinstance(tgt, N.Array):
            a, first = self.arr(tgt.name, True), "0"
        elif isinstance(tgt, N.Index) and len(tgt.index) == 1:
            a, first = self.arr(tgt.name, True), self.index(tgt.index)
        else:
            raise CompileError(line, "DECOMPOSE needs an array", "DECOMPOSE", tgt)
        self.guarded(line, [f"_decompose({a}, {first}, {self.val(st.value)[0]}, {self.is_double(tgt.name)!r})"])

    def visit_Switch(self, line: int, st: N.Switch) -> None:
        self.guarded(line, [f"_switch(T, {list(st.names)!r}, {st.word == 'ENABLE'!r})"])

    def visit_TimerSet(self, line: int, st: N.TimerSet) -> None:
        self.guarded(line, [f"_timer_set({self.val(st.timer)[0]}, {self.val(st.value)[0]})"])

    def visit_Hand(self, line: int, st: N.Hand) -> None:
        # OPEN/CLOSE/RELAX act as the next motion starts; the I forms wait for rest and hold for HAND.TIME
        self.guarded(line, [f"yield from _hand(T, {st.word!r})"])

    def visit_Parameter(self, line: int, st: N.Parameter) -> None:
        if st.name != "HAND.TIME":
            raise CompileError(line, f"PARAMETER {st.name} is not implemented by the emulator", "PARAMETER", st)
        self.guarded(line, [f"_parameter(T, {st.name!r}, {self.val(st.value)[0]})"])

    def visit_Select(self, line: int, st: N.Select) -> None:
        self.guarded(line, [f"_select(T, {st.device!r}, {self.val(st.unit)[0]})"])

    def visit_Calibrate(self, line: int, st: N.Calibrate) -> None:
        mode = "None" if st.mode is None else self.val(st.mode)[0]
        status = "None" if st.status is None else "({}, {})".format(*self.ref(st.status))
        self.guarded(line, [f"yield from _calibrate(T, {mode}, {status})"])

    def visit_Bits(self, line: int, st: N.Bits) -> None:
        count = "1.0" if st.count is None else self.val(st.count)[0]
        self.guarded(line, [f"_bits_set(T, {self.val(st.first)[0]}, {count}, {self.val(st.value)[0]})"])

    def call_args(self, args: tuple) -> str:
        out = []
        for a in args:
            if a is None:
                out.append("_MISSING")
            elif isinstance(a, N.Name):
                c, key = self.scope(a.name)
                out.append(f"({c}, {key})")
            elif isinstance(a, N.Index):
                out.append(f"({self.arr(a.name, True)}, {self.index(a.index)})")
            elif isinstance(a, N.Array):
                out.append(self.arr(a.name, True))
            else:
                code, typ = self.val(a)
                out.append(f"([_byval({code})], 0)")
        return ", ".join(out) + ("," if len(out) == 1 else "")


_SPECIAL_CALLS = {"$DECODE": "call_decode", "$ENCODE": "call_encode", "DEFINED": "call_defined",
                  "LAST": "call_last", "LEN": "call_len"}
"""Functions whose code is not a plain call of the built-in (an argument passed by reference, a format)."""


def _word(e: N.Expr) -> str:
    """The word of an expression for a message: its name, or its value."""
    return str(getattr(e, "name", getattr(e, "value", "")))


def _uses_goto(steps) -> bool:
    return any(isinstance(st, (N.Label, N.Goto, N.IfGoto)) for _, st in steps)


def _has_label(body: list) -> bool:
    """Whether a label is in a body or in a block inside it."""
    return any(_has_label(it.body) or _has_label(it.orelse) or any(_has_label(b) for _, b in it.cases)
               if isinstance(it, _Block) else isinstance(it[1], N.Label) for it in body)


def _direct_next(body: list) -> bool:
    for it in body:
        if isinstance(it, _Block):
            if it.kind in ("IF", "CASE"):
                if _direct_next(it.body) or _direct_next(it.orelse) or any(_direct_next(b) for _, b in it.cases):
                    return True
        elif isinstance(it[1], N.LoopJump) and it[1].word == "NEXT":
            return True
    return False


def _fname(name: str) -> str:
    """Code calling the built-in function ``name``: a global of the generated code bound to it (``_fn_ASC``,
    ``_fn_sMID``; see builtins.namespace), which saves the ``_fn[...]`` look-up of each call. A name that is not a
    Python identifier once mangled goes through the table."""
    py = "_fn_" + name.replace("$", "s").replace("#", "h").replace(".", "_")
    return py if py.isidentifier() else f"_fn[{name!r}]"


def _local(name: str) -> str:
    """The Python local of an AUTO scalar: ``$id`` -> ``V_sid``, ``rs.x`` -> ``V_rs_dx`` (one-to-one)."""
    return "V_" + name.replace("_", "_u").replace(".", "_d").replace("$", "_s").replace("#", "_h")


def vplus_name(local: str) -> str:
    """The V+ name of a Python local made by :func:`_local` (for the *Undefined value* message)."""
    out, i, s = [], 0, local[2:]
    while i < len(s):
        if s[i] == "_" and i + 1 < len(s):
            out.append({"u": "_", "d": ".", "s": "$", "h": "#"}.get(s[i + 1], s[i + 1]))
            i += 2
        else:
            out.append(s[i])
            i += 1
    return "".join(out)


def compile_program(prog: Program, doubles: set[str], *, traced: bool = False, variables: bool = True
                    ) -> tuple[str | None, list[Any], list[LoadProblem]]:
    """Python source of one program (defines ``_prog``) and its constants, or the problems that prevent it.

    AUTO scalars become Python locals (a local is a few times cheaper than ``L['name']``), except those the
    program passes on by reference (a CALL argument, the string of ``$DECODE``, a READ target or I/O handle,
    ``DEFINED``): the callee or the built-in writes through a ``(container, key)`` pair, so those stay in ``L``.
    Which they are is known after generating the code once; a second pass keeps them in ``L``.

    ``traced``: the instrumented form (a line hook before each statement, every AUTO in ``L``); its constants
    end with the V+ line of each line of the Python source (index: Python line - 1), read by the tracer for the
    line a caller's frame is at. ``variables=False``: the AUTOs stay Python locals as in the plain form (a line
    hook that reads no variable, as line coverage's, costs the hook's test only).
    """
    boxed: frozenset[str] = frozenset()
    for _ in range(3):
        gen = _Gen(prog, doubles, boxed, traced, variables)
        src = gen.program()
        if gen.problems:
            return None, [], [_problem(prog, exc) for exc in gen.problems]
        if gen.boxed <= boxed:
            return src, gen.consts + [tuple(gen.line_of)] if traced else gen.consts, []
        boxed = boxed | gen.boxed
    raise AssertionError("AUTOs passed by reference did not settle")  # pragma: no cover - boxed only grows


def _problem(prog: Program, exc: CompileError) -> LoadProblem:
    """A compile problem as the loader's: its line, and its column at the offending word (in the node that
    caused it, else at the node, else 0)."""
    line = exc.line or prog.line
    col = 0
    span = exc.node.span if exc.node is not None else None
    if span is not None and span.line == line and span.col:
        col = span.col
        code = prog.source.get(line, "")
        indent = prog.indent.get(line, 0)
        at = code.upper().find(exc.word.upper(), max(span.col - 1 - indent, 0)) if exc.word else -1
        if at >= 0:
            col = indent + at + 1
    return LoadProblem(prog.file, line, exc.message, exc.word, prog.name, col)
