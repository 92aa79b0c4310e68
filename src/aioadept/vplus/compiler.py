"""V+ programs to Python: each ``.PROGRAM`` becomes one generator function.

(Over 500 lines because each V+ statement kind has its code generator here, all writing into one generated
function with one shared scope of labels and locals; a split by statement kind would pass that scope around.)

Why generate Python source: a tree-walking interpreter in Python runs a simple V+ statement in several
microseconds; generated code runs it as a few bytecodes (a dict store, an ``array('f')`` round trip for REAL
precision). Structured control (IF, WHILE, DO, FOR, CASE) becomes native Python control flow. A program that uses
GOTO is cut into segments at its labels (labels must be at the top level of the program) and runs in a small
dispatch loop.

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

from aioadept.vplus.loader import LoadProblem, Program

BUDGET = 2000
"""Loop iterations a task runs before it yields its time slice (virtual time; the generated code reads the
runtime's ``_BUDGET``, which is smaller in real time, where the slice is measured on the clock)."""

_LOC_FUNCS = {"TRANS", "INVERSE", "HERE", "RX", "RY", "RZ", "NULL"}
_PP_FUNCS = {"#PPOINT", "#HERE"}
_STR_FUNCS = {"$DECODE", "$ENCODE", "$MID", "$CHR", "$ERROR", "$TRUNCATE", "$LEFT", "$RIGHT", "$TOUPPER",
              "$TOLOWER", "$TIME", "$DEFAULT"}
_FMT_RE = re.compile(r"([A-Z])(\d+)?(?:\.(\d+))?\Z")       # as builtins._FMT_RE
_BLOCK_OPEN = {"IF", "WHILE", "DO", "FOR", "CASE"}


class CompileError(Exception):
    def __init__(self, line: int, message: str, word: str) -> None:
        super().__init__(message)
        self.line, self.message, self.word = line, message, word


@dataclass
class _Block:
    kind: str
    line: int
    head: Any
    body: list = field(default_factory=list)
    orelse: list = field(default_factory=list)        # IF: ELSE part
    cases: list = field(default_factory=list)         # CASE: [(values or None for ANY, body)]
    until: Any = None


def _nest(steps: list[tuple[int, Any]]) -> list:
    """Flat steps to a tree of :class:`_Block` and ``(line, stmt)`` items; raises :class:`CompileError`."""
    root: list = []
    stack: list[tuple[_Block | None, list]] = [(None, root)]
    for line, st in steps:
        kind = st[0]
        if kind == "LABEL":
            if len(stack) > 1:
                raise CompileError(line, "a label inside a block is not supported by the emulator", str(st[1]))
            stack[-1][1].append((line, ("LABEL", st[1], None)))
            if st[2] is None:
                continue
            st = st[2]
            kind = st[0]
        if kind in _BLOCK_OPEN:
            blk = _Block(kind, line, st)
            stack[-1][1].append(blk)
            stack.append((blk, blk.body))
        elif kind == "ELSE":
            blk = stack[-1][0]
            if blk is None or blk.kind != "IF" or stack[-1][1] is blk.orelse:
                raise CompileError(line, "ELSE without IF", "ELSE")
            stack[-1] = (blk, blk.orelse)
        elif kind in ("VALUE", "ANY"):
            blk = stack[-1][0]
            if blk is None or blk.kind != "CASE":
                raise CompileError(line, f"{kind} outside CASE", kind)
            body: list = []
            blk.cases.append((st[1] if kind == "VALUE" else None, body))
            stack[-1] = (blk, body)
        elif kind == "END":
            blk = stack[-1][0]
            if blk is None:
                raise CompileError(line, "END without an open block", "END")
            if blk.kind == "DO":
                raise CompileError(line, "DO closed by END instead of UNTIL", "END")
            stack.pop()
        elif kind == "UNTIL":
            blk = stack[-1][0]
            if blk is None or blk.kind != "DO":
                raise CompileError(line, "UNTIL without DO", "UNTIL")
            blk.until = st[1]
            stack.pop()
        else:
            stack[-1][1].append((line, st))
    if len(stack) > 1:
        blk = stack[-1][0]
        raise CompileError(blk.line, f"{blk.kind} not closed", blk.kind)
    return root


class _Gen:
    def __init__(self, prog: Program, doubles: set[str], boxed: frozenset[str] = frozenset()) -> None:
        self.prog = prog
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
        self.labels: dict[int, int] = {}

    # -- output ---------------------------------------------------------------------------------------------
    def emit(self, s: str) -> None:
        for ln in s.split("\n"):
            self.lines.append("    " * self.ind + ln)

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

    def index(self, idx: list) -> str:
        parts = []
        for e in idx:
            if e[0] == "num" and e[1] >= 0:
                # rounded, not truncated (V+ Language User's Guide v17, p. 102), as builtins.vint does at run time
                parts.append(repr(int(math.floor(e[1] + 0.5))))
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
    def val(self, e) -> tuple[str, str]:
        k = e[0]
        if k == "num":
            return repr(float(e[1])), "num"
        if k == "str":
            return repr(e[1]), "str"
        if k == "var":
            return self.lv(e[1]), self.vtype(e[1])
        if k == "paren":
            return self.val(e[1])             # (x) as a CALL argument: its value (passed by value)
        if k == "idx":
            return f"{self.arr(e[1], False)}[{self.index(e[2])}]", self.vtype(e[1])
        if k == "arr":
            raise CompileError(0, "an array (name[]) is not a value here", e[1] + "[]")
        if k == "fmt":
            raise CompileError(0, "a format is not a value here", "/" + e[1])
        if k == "un":
            if e[1] == "-":
                return f"(-{self.val(e[2])[0]})", "num"
            if e[1] == "NOT":
                return f"(0.0 if {self.cond(e[2])} else -1.0)", "num"
            return f"float(~int({self.val(e[2])[0]}))", "num"
        if k == "bin":
            return self.binop(e)
        if k == "call":
            return self.call(e)
        if k == "shift":
            d = ["0.0" if x is None else self.val(x)[0] for x in e[2]]
            return f"{_fname('SHIFT')}({self.val(e[1])[0]}, {', '.join(d)})", "loc"
        raise CompileError(0, f"cannot compile {k}", str(k))  # pragma: no cover

    def vtype(self, name: str) -> str:
        return "str" if name.startswith("$") else ("pp" if name.startswith("#") else "any")

    def binop(self, e) -> tuple[str, str]:
        op, a, b = e[1], e[2], e[3]
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

    def cond(self, e) -> str:
        """Python boolean expression for a V+ condition (non-zero is TRUE)."""
        if e[0] == "bin":
            op = e[1]
            if op == "AND":
                return f"({self.cond(e[2])} and {self.cond(e[3])})"
            if op == "OR":
                return f"({self.cond(e[2])} or {self.cond(e[3])})"
            if op == "XOR":
                return f"(bool({self.cond(e[2])}) != bool({self.cond(e[3])}))"
            if op in ("==", "<>", "<", ">", "<=", ">="):
                pyop = "!=" if op == "<>" else op
                ca, ta = self.val(e[2])
                cb, tb = self.val(e[3])
                if ("str" in (ta, tb)) and ta != tb and "any" not in (ta, tb):
                    raise CompileError(0, "comparison of a string with a number", op)
                return f"({ca} {pyop} {cb})"
        if e[0] == "un" and e[1] == "NOT":
            return f"(not {self.cond(e[2])})"
        return f"({self.val(e)[0]} != 0)"

    def call(self, e) -> tuple[str, str]:
        name, args = e[1], e[2]
        if name == "$DECODE":
            if len(args) != 3 or args[0] is None or args[0][0] not in ("var", "idx"):
                raise CompileError(0, "$DECODE needs a string variable, breaks and a mode", name)
            c, key = self.ref(args[0])
            return f"_decode({c}, {key}, {self.val(args[1])[0]}, {self.val(args[2])[0]})", "str"
        if name == "$ENCODE":
            return self.encode(args), "str"
        if name == "DEFINED":
            if len(args) != 1 or args[0] is None:
                raise CompileError(0, "DEFINED needs one variable", name)
            a = args[0]
            if a[0] == "var":
                c, key = self.scope(a[1])
                if a[1] in self.params:
                    # a parameter's container is a dict, or the one-element list of a value passed by value
                    return f"_defref({c}, {key})", "num"
                return f"(-1.0 if {key} in {c} else 0.0)", "num"
            if a[0] == "arr":
                return f"_defarr(lambda: {self.arr(a[1], False)})", "num"
            if a[0] == "idx":
                return f"_defined(lambda: {self.val(a)[0]})", "num"
            raise CompileError(0, "DEFINED needs a variable", name)
        if name == "LAST":
            if len(args) != 1 or args[0] is None or args[0][0] != "arr":
                raise CompileError(0, "LAST needs an array: LAST(a[])", name)
            return f"_last(lambda: {self.arr(args[0][1], False)})", "num"
        if name == "LEN":
            return f"float(len({self.val(args[0])[0]}))", "num"
        vals = ", ".join("None" if a is None else self.val(a)[0] for a in args)
        if name in ("IOSTAT", "ERROR", "TASK", "INRANGE", "HERE", "#HERE", "SPEED"):
            vals = "T" + (", " + vals if vals else "")
        typ = "loc" if name in _LOC_FUNCS else ("pp" if name in _PP_FUNCS else
                                                ("str" if name in _STR_FUNCS else "num"))
        return f"{_fname(name)}({vals})", typ

    def encode(self, args: list) -> str:
        """$ENCODE with its formats applied at compile time (they are constants): each number goes through
        ``_encv`` with its format, strings are joined as they are. A format the emulator does not know takes
        the general path (``_encode``), which reports it when the line runs."""
        parts: list[str] = []
        spec: tuple = ("D", None, None)
        for a in args:
            if a is None:
                continue
            if a[0] == "fmt":
                f = a[1]
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

    def items(self, args: list) -> str:
        """Output items (formats and values) as a tuple body for _encode/_type/_write."""
        out = []
        for a in args:
            if a is None:
                continue
            if a[0] == "fmt":
                out.append(self.const(("fmt", a[1])))
            else:
                out.append(self.val(a)[0])
        return ", ".join(out) + ("," if len(out) == 1 else "")

    def ref(self, e) -> tuple[str, str]:
        """(container, key) of an assignable variable or array element."""
        if e[0] == "var":
            return self.scope(e[1])
        if e[0] == "idx":
            return self.arr(e[1], True), self.index(e[2])
        raise CompileError(0, "expected a variable", str(e[1]))

    def store(self, target, code: str, typ: str, force_loc: bool = False) -> str:
        """A Python statement storing ``code`` into the V+ variable ``target``."""
        t = self.target(target)
        name = target[1]
        if name.startswith("$"):
            # _str's checks inline: most stores are short strings
            return f"{t} = _t if type(_t := {code}) is str and len(_t) <= 128 else _str(_t)"
        if name.startswith("#"):
            return f"{t} = _pp({code})"
        if force_loc or typ == "loc":
            if target[0] == "idx":
                # an array holds one type (V+ Language User's Guide v17, p. 105): a location array is a _LocArray
                c, key = ("L", repr(name + "[]")) if name in self.autos else (
                    ("S", repr(name + "[]")) if name in self.statics else ("G", repr(name + "[]")))
                arr = self.arr(name, False) if name in self.params else "None"
                return f"_loc_store({c}, {key}, {arr}, {self.index(target[2])}, _loc({code}), {name!r})"
            return f"{t} = _loc({code})"
        if self.is_double(name):
            return f"{t} = _dbl({code})"
        if typ == "num":
            return f"_F[0] = {code}; {t} = _F[0]"
        return f"_t = {code}\nif type(_t) is float: _F[0] = _t; {t} = _F[0]\nelse: {t} = _real(_t)"

    def target(self, e) -> str:
        """Code of an assignable variable or array element (assigned in the generated code itself)."""
        if e[0] == "var":
            return self.lv(e[1])
        if e[0] == "idx":
            return f"{self.arr(e[1], True)}[{self.index(e[2])}]"
        raise CompileError(0, "expected a variable", str(e[1]))

    # -- statements -----------------------------------------------------------------------------------------
    def declare(self, steps) -> None:
        executable = False
        for line, st in steps:
            if st[0] == "LABEL":
                if st[2] is None:
                    continue
                st = st[2]
            if st[0] in ("AUTO", "LOCAL", "GLOBAL"):
                if executable:
                    # V+ Language User's Guide v17, p. 36 ("Program Organization")
                    raise CompileError(line, f"{st[0]} after an executable instruction (AUTO, LOCAL and GLOBAL "
                                             "must precede every executable instruction)", st[0])
            elif st[0] != "NOP":
                executable = True
            if st[0] in ("AUTO", "LOCAL"):
                for name, typ, is_arr in st[1]:
                    if name in self.params:
                        raise CompileError(line, f"{name} is a parameter", name)
                    (self.autos if st[0] == "AUTO" else self.statics)[name] = typ
            elif st[0] == "GLOBAL":
                for name, typ, is_arr in st[1]:
                    if typ == "DOUBLE":
                        self.doubles.add(name)

    def program(self) -> str:
        p = self.prog
        tree = _nest(p.steps)
        self.declare(p.steps)
        self.fast = {n for n in self.autos if n not in self.keep_boxed}
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
        for name, typ in self.autos.items():
            pass
        self.emit("_b = _BUDGET")
        has_goto = any(isinstance(it, tuple) and it[1][0] == "LABEL" for it in tree) or _uses_goto(p.steps)
        if has_goto:
            self.goto_program(tree)
        else:
            self.block(tree)
        self.emit("return")
        self.emit("yield")
        return "\n".join(self.lines)

    def goto_program(self, tree: list) -> None:
        segs: list[list] = [[]]
        for it in tree:
            if isinstance(it, tuple) and it[1][0] == "LABEL":
                self.labels[it[1][1]] = len(segs)
                segs.append([])
            else:
                segs[-1].append(it)
        self.emit("_pc = 0")
        self.emit("while True:")
        self.ind += 1
        self.emit("try:")
        self.ind += 1
        for k, seg in enumerate(segs):
            self.emit(f"if _pc <= {k}:")
            self.ind += 1
            self.emit("pass")
            self.block(seg)
            self.ind -= 1
        self.emit("break")
        self.ind -= 1
        self.emit("except _Goto as _g:")
        self.ind += 1
        self.emit("_pc = _g.pc")
        self.budget()
        self.ind -= 2

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
                self.compound(it)
            else:
                line, st = it
                if st[0] in ("AUTO", "LOCAL", "GLOBAL", "NOP", "LABEL"):
                    continue
                try:
                    self.simple(line, st)
                except CompileError as exc:
                    raise CompileError(line, exc.message, exc.word) from None

    def guarded(self, line: int, code_lines: list[str]) -> None:
        self.emit("try:")
        for c in code_lines:
            self.emit("\n".join("    " + ln for ln in c.split("\n")))
        self.emit("except Exception as _e:")
        self.emit(f"    yield from _err(T, _e, {self.prog.name!r}, {line})")

    def guarded_cond(self, line: int, e) -> str:
        try:
            c = self.cond(e)
        except CompileError as exc:
            raise CompileError(line, exc.message, exc.word) from None
        v = self.tmp("_c")
        self.emit("try:")
        self.emit(f"    {v} = {c}")
        self.emit("except Exception as _e:")
        self.emit(f"    yield from _err(T, _e, {self.prog.name!r}, {line}); {v} = False")
        return v

    def compound(self, b: _Block) -> None:
        k = b.kind
        if k == "IF":
            c = self.guarded_cond(b.line, b.head[1])
            self.emit(f"if {c}:")
            self.ind += 1
            self.block(b.body)
            self.ind -= 1
            if b.orelse:
                self.emit("else:")
                self.ind += 1
                self.block(b.orelse)
                self.ind -= 1
        elif k == "WHILE":
            self.emit("while True:")
            self.ind += 1
            c = self.guarded_cond(b.line, b.head[1])
            self.emit(f"if not {c}: break")
            self.loops.append("WHILE")
            self.block(b.body)
            self.loops.pop()
            self.budget()
            self.ind -= 1
        elif k == "DO":
            if _direct_next(b.body):
                raise CompileError(b.line, "NEXT inside DO ... UNTIL is not supported by the emulator", "NEXT")
            self.emit("while True:")
            self.ind += 1
            self.loops.append("DO")
            self.block(b.body)
            self.loops.pop()
            self.budget()
            c = self.guarded_cond(b.line, b.until)
            self.emit(f"if {c}: break")
            self.ind -= 1
        elif k == "FOR":
            self.for_loop(b)
        elif k == "CASE":
            v = self.tmp("_v")
            try:
                code = self.val(b.head[1])[0]
                vals = [[self.val(x)[0] for x in vs] if vs is not None else None for vs, _ in b.cases]
            except CompileError as exc:
                raise CompileError(b.line, exc.message, exc.word) from None
            self.guarded(b.line, [f"{v} = {code}"])
            first = True
            for (vs, body), codes in zip(b.cases, vals):
                if vs is None:
                    self.emit("else:" if not first else "if True:")
                else:
                    test = " or ".join(f"{v} == {c}" for c in codes)
                    self.emit(("if " if first else "elif ") + test + ":")
                first = False
                self.ind += 1
                self.block(body)
                self.ind -= 1

    def for_loop(self, b: _Block) -> None:
        _, var, start, end, step = b.head
        try:
            v = self.target(var)
            scode = self.val(start)[0]
            ecode = self.val(end)[0]
            stcode = "1.0" if step is None else self.val(step)[0]
        except CompileError as exc:
            raise CompileError(b.line, exc.message, exc.word) from None
        e, s = self.tmp("_e"), self.tmp("_s")
        dbl = self.is_double(var[1])
        conv = "_dbl" if dbl else "_f32"
        self.guarded(b.line, [f"{e} = float({ecode}); {s} = float({stcode})", f"{v} = {conv}({scode})"])
        const_pos = step is None or (step[0] == "num" and step[1] > 0)
        test = f"{v} <= {e}" if const_pos else f"({v} <= {e} if {s} > 0 else {v} >= {e})"
        if dbl:
            inc = f"{v} = {v} + {s}"
        else:
            inc = f"_F[0] = {v} + {s}; {v} = _F[0]"
        self.loops.append("FOR")
        if _direct_next(b.body):
            f = self.tmp("_first")
            self.emit(f"{f} = True")
            self.emit("while True:")
            self.ind += 1
            self.emit(f"if not {f}: {inc}")
            self.emit(f"{f} = False")
            self.emit(f"if not ({test}): break")
            self.block(b.body)
            self.budget()
            self.ind -= 1
        else:
            self.emit(f"while {test}:")
            self.ind += 1
            self.block(b.body)
            self.budget()
            self.emit(inc)
            self.ind -= 1
        self.loops.pop()

    def simple(self, line: int, st) -> None:
        k = st[0]
        name = self.prog.name
        if k == "ASSIGN":
            _, target, expr, is_set = st
            code, typ = self.val(expr)
            if target[0] == "arr":
                raise CompileError(line, "cannot assign to a whole array", target[1])
            if not is_set and (typ in ("loc", "pp") or target[1].startswith("#")):
                # V+ Language User's Guide v17, p. 111 ("Assignment Operator")
                raise CompileError(line, "a location is assigned with SET (SET name = value)", target[1])
            self.guarded(line, [self.store(target, code, typ, is_set and not target[1].startswith(("$", "#")))])
        elif k == "GOTO":
            if st[1] not in self.labels:
                raise CompileError(line, f"GOTO to an undefined label {st[1]}", str(st[1]))
            self.emit(f"raise _GOTO[{self.labels[st[1]]}]")
        elif k == "IFGOTO":
            if st[2] not in self.labels:
                raise CompileError(line, f"GOTO to an undefined label {st[2]}", str(st[2]))
            c = self.guarded_cond(line, st[1])
            self.emit(f"if {c}: raise _GOTO[{self.labels[st[2]]}]")
        elif k in ("RETURN", "RETURNE"):
            self.emit("return")
        elif k in ("EXIT", "NEXT"):
            if not self.loops:
                raise CompileError(line, f"{k} outside a loop", k)
            if st[1] != 1:
                raise CompileError(line, f"{k} with a count is not supported by the emulator", k)
            self.emit("break" if k == "EXIT" else "continue")
        elif k == "CALL":
            args = self.call_args(st[2])
            self.guarded(line, [f"yield from _call(T, {st[1]!r}, ({args}))"])
        elif k == "CALLS":
            args = self.call_args(st[2])
            self.guarded(line, [f"yield from _call(T, _progname({self.val(st[1])[0]}), ({args}))"])
        elif k == "WAIT":
            if st[1] is None:
                self.guarded(line, ["yield _tick()"])
            else:
                c = self.cond(st[1])
                self.guarded(line, [f"while not {c}:", "    yield _ctick(T)"])
        elif k == "HALT":
            self.guarded(line, [f"_halt(T, {name!r}, {line})"])
        elif k == "STOP":
            self.guarded(line, [f"_stop(T)"])
        elif k == "PAUSE":
            self.guarded(line, [f"yield from _pause(T, {name!r}, {line})"])
        elif k == "TYPE":
            self.guarded(line, [f"_type(T, ({self.items(st[1])}))"])
        elif k == "PROMPT":
            items = [x for x in st[1] if x is not None]
            targets = [x for x in items if x[0] in ("var", "idx")]
            texts = [x for x in items if x[0] not in ("var", "idx")]
            lines = [f"_type(T, ({self.items(texts)} {self.const(('fmt', 'S'))},))"]
            for t in targets:
                v = self.tmp("_in")
                lines.append(f"{v} = yield from _prompt(T, {t[1].startswith('$')!r})")
                lines.append(self.store(t, v, "str" if t[1].startswith("$") else "num"))
            self.guarded(line, lines)
        elif k == "SIGNAL":
            vals = ", ".join(self.val(e)[0] for e in st[1])
            self.guarded(line, [f"_signal(T, ({vals},))"])
        elif k == "WAIT.EVENT":
            vals = ", ".join("None" if e is None else self.val(e)[0] for e in st[1])
            self.guarded(line, [f"yield from _wait_event(T, ({vals}{',' if vals else ''}))"])
        elif k == "SET.EVENT":
            vals = ", ".join("None" if e is None else self.val(e)[0] for e in st[1])
            self.guarded(line, [f"_set_event(T, ({vals}{',' if vals else ''}))"])
        elif k in ("ATTACH", "DETACH", "FCLOSE", "FOPEN"):
            args = st[1]
            refs = []
            for i, a in enumerate(args):
                if a is None:
                    refs.append("None")
                elif i == 0 and a[0] in ("var", "idx"):
                    c, key = self.ref(a)
                    refs.append(f"({c}, {key})")
                else:
                    refs.append(f"(None, {self.val(a)[0]})")
            text = self.items(st[2]) if st[2] else ""
            self.guarded(line, [f"yield from _io_{k.lower()}(T, ({', '.join(refs)}{',' if len(refs) == 1 else ''}), "
                                f"({text}))"])
        elif k == "READ":
            args = st[1]
            lun = self.val(args[0])[0] if args and args[0] is not None else "None"
            handle = "None"
            if len(args) > 1 and args[1] is not None:
                if args[1][0] not in ("var", "idx"):
                    raise CompileError(line, "READ handle must be a variable", "READ")
                c, key = self.ref(args[1])
                handle = f"({c}, {key})"
            mode = self.val(args[2])[0] if len(args) > 2 and args[2] is not None else "0.0"
            tgts = ", ".join("({}, {})".format(*self.ref(t)) for t in st[2])
            self.guarded(line, [f"yield from _io_read(T, {lun}, {handle}, {mode}, ({tgts}{',' if len(st[2]) == 1 else ''}))"])
        elif k == "WRITE":
            args = st[1]
            lun = self.val(args[0])[0] if args and args[0] is not None else "None"
            handle = self.val(args[1])[0] if len(args) > 1 and args[1] is not None else "None"
            self.guarded(line, [f"yield from _io_write(T, {lun}, {handle}, ({self.items(st[2])}))"])
        elif k == "EXECUTE":
            _, task, prog, args, extra = st
            tcode = self.val(task)[0] if task is not None else "None"
            vals = ", ".join("None" if a is None else self.val(a)[0] for a in args)
            self.guarded(line, [f"_execute(T, {tcode}, {prog!r}, ({vals}{',' if len(args) == 1 else ''}))"])
        elif k in ("ABORT", "KILL", "CYCLE.END"):
            vals = ", ".join(self.val(e)[0] for e in st[1])
            fn = {"ABORT": "_abort", "KILL": "_kill", "CYCLE.END": "_cycle_end"}[k]
            self.guarded(line, [f"{fn}(T, ({vals}{',' if len(st[1]) == 1 else ''}))"])
        elif k == "REACTE":
            self.guarded(line, [f"_reacte(T, {st[1]!r})"])
        elif k in ("MOVE", "MOVES", "DEPART", "DEPARTS", "DELAY"):
            self.guarded(line, [f"yield from _robot(T, {k!r}, {self.val(st[1])[0]})"])
        elif k in ("APPRO", "APPROS", "MOVET", "MOVEST"):
            self.guarded(line, [f"yield from _robot(T, {k!r}, {self.val(st[1])[0]}, {self.val(st[2])[0]})"])
        elif k == "DURATION":
            self.guarded(line, [f"_duration(T, {self.val(st[1])[0]}, {st[2]!r})"])
        elif k == "CONFIG":
            self.guarded(line, [f"_config(T, {st[1]!r})"])
        elif k == "DISKOPEN":
            args = st[2]
            if len(args) != 1 or args[0] is None:
                raise CompileError(line, f"{st[1]} needs (lun)", st[1])
            self.guarded(line, [f"_disk_open(T, {st[1]!r}, {self.val(args[0])[0]}, ({self.items(st[3])}))"])
        elif k in ("BREAK",):
            self.guarded(line, ["yield from _robot(T, 'BREAK')"])
        elif k == "BRAKE":
            self.guarded(line, ["_brake(T)"])
        elif k == "SPEED":
            self.guarded(line, [f"_speed(T, {self.val(st[1])[0]}, {st[2]!r})"])
        elif k == "ACCEL":
            vals = ", ".join(self.val(e)[0] for e in st[1])
            self.guarded(line, [f"_accel(T, ({vals},))"])
        elif k == "TOOL":
            self.guarded(line, [f"_tool(T, {self.val(st[1])[0]})"])
        elif k == "HERE":
            tgt = st[1]
            fn = f"{_fname('#HERE')}(T)" if tgt[1].startswith("#") else f"{_fname('HERE')}(T)"
            self.guarded(line, [self.store(tgt, fn, "pp" if tgt[1].startswith("#") else "loc")])
        elif k == "DECOMPOSE":
            tgt = st[1]
            if tgt[0] == "arr":
                a, first = self.arr(tgt[1], True), "0"
            elif tgt[0] == "idx" and len(tgt[2]) == 1:
                a, first = self.arr(tgt[1], True), self.index(tgt[2])
            else:
                raise CompileError(line, "DECOMPOSE needs an array", "DECOMPOSE")
            self.guarded(line, [f"_decompose({a}, {first}, {self.val(st[2])[0]}, "
                                f"{self.is_double(tgt[1])!r})"])
        elif k in ("ENABLE", "DISABLE"):
            self.guarded(line, [f"_switch(T, {st[1]!r}, {k == 'ENABLE'!r})"])
        elif k == "TIMERSET":
            self.guarded(line, [f"_timer_set({self.val(st[1])[0]}, {self.val(st[2])[0]})"])
        elif k == "HAND":
            # OPEN/CLOSE/RELAX act as the next motion starts; the I forms wait for rest and hold for HAND.TIME
            self.guarded(line, [f"yield from _hand(T, {st[1]!r})"])
        elif k == "PARAMETER":
            if st[1] != "HAND.TIME":
                raise CompileError(line, f"PARAMETER {st[1]} is not implemented by the emulator", "PARAMETER")
            self.guarded(line, [f"_parameter(T, {st[1]!r}, {self.val(st[2])[0]})"])
        elif k == "BITS":
            count = "1.0" if st[2] is None else self.val(st[2])[0]
            self.guarded(line, [f"_bits_set(T, {self.val(st[1])[0]}, {count}, {self.val(st[3])[0]})"])
        elif k == "NULL":
            pass
        else:
            raise CompileError(line, f"instruction {k} is not implemented by the emulator", k)

    def call_args(self, args: list) -> str:
        out = []
        for a in args:
            if a is None:
                out.append("_MISSING")
            elif a[0] == "var":
                c, key = self.scope(a[1])
                out.append(f"({c}, {key})")
            elif a[0] == "idx":
                out.append(f"({self.arr(a[1], True)}, {self.index(a[2])})")
            elif a[0] == "arr":
                out.append(self.arr(a[1], True))
            else:
                code, typ = self.val(a)
                out.append(f"([_byval({code})], 0)")
        return ", ".join(out) + ("," if len(out) == 1 else "")


def _uses_goto(steps) -> bool:
    for _, st in steps:
        if st[0] == "LABEL":
            return True
        if st[0] in ("GOTO", "IFGOTO"):
            return True
    return False


def _direct_next(body: list) -> bool:
    for it in body:
        if isinstance(it, _Block):
            if it.kind in ("IF", "CASE"):
                if _direct_next(it.body) or _direct_next(it.orelse) or any(_direct_next(b) for _, b in it.cases):
                    return True
        elif it[1][0] == "NEXT":
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


def compile_program(prog: Program, doubles: set[str]) -> tuple[str | None, list[Any], list[LoadProblem]]:
    """Python source of one program (defines ``_prog``) and its constants, or the problems that prevent it.

    AUTO scalars become Python locals (a local is a few times cheaper than ``L['name']``), except those the
    program passes on by reference (a CALL argument, the string of ``$DECODE``, a READ target or I/O handle,
    ``DEFINED``): the callee or the built-in writes through a ``(container, key)`` pair, so those stay in ``L``.
    Which they are is known after generating the code once; a second pass keeps them in ``L``.
    """
    boxed: frozenset[str] = frozenset()
    for _ in range(3):
        gen = _Gen(prog, doubles, boxed)
        try:
            src = gen.program()
        except CompileError as exc:
            word = exc.word
            return None, [], [LoadProblem(prog.file, exc.line or prog.line, exc.message, word, prog.name)]
        if gen.boxed <= boxed:
            return src, gen.consts, []
        boxed = boxed | gen.boxed
    raise AssertionError("AUTOs passed by reference did not settle")  # pragma: no cover - boxed only grows
