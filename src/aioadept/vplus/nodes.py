"""The V+ syntax tree: one frozen dataclass per statement and expression form, each with its source span.

:mod:`aioadept.vplus.parse` makes them from a line of source, :mod:`aioadept.vplus.compiler` visits them by type
(``visit_<Class>``), :func:`render` turns one back into source text. A span is 1-based: the line, the first
column and the column after the last character, so a language server can point at a sub-expression and a
debugger can evaluate one. Sequences are tuples (nodes are values); an omitted argument (``READ (lun, , 0)``)
is ``None``.

Nothing here parses, compiles or runs code.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields


@dataclass(frozen=True, slots=True)
class Span:
    """Where a node is: ``file``, ``line``, first column ``col`` and the column after it ``end`` (1-based)."""

    file: str = ""
    line: int = 0
    col: int = 0
    end: int = 0


NOSPAN = Span()


@dataclass(frozen=True, slots=True)
class Node:
    """A node of the tree; ``span`` is where its text is (not part of its identity)."""

    span: Span = field(default=NOSPAN, compare=False, repr=False, kw_only=True)

    def children(self) -> tuple:
        """The nodes directly below this one (sub-expressions, argument lists flattened)."""
        out: list = []
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, Node) and f.name != "span":
                out.append(v)
            elif isinstance(v, tuple):
                out.extend(x for x in v if isinstance(x, Node))
        return tuple(out)


# -- expressions ----------------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class Expr(Node):
    """An expression; ``parens`` counts the parentheses written around it (they change no value)."""

    parens: int = field(default=0, compare=False, repr=False, kw_only=True)


@dataclass(frozen=True, slots=True)
class Num(Expr):
    value: float
    text: str = field(default="", compare=False, repr=False, kw_only=True)    # as written: ^H10, 'A, PI


@dataclass(frozen=True, slots=True)
class Str(Expr):
    value: str
    bare: bool = field(default=False, compare=False, repr=False, kw_only=True)   # written without quotes


@dataclass(frozen=True, slots=True)
class Name(Expr):
    """A scalar variable (normalised name, see :func:`aioadept.vplus.parse.norm`)."""

    name: str


@dataclass(frozen=True, slots=True)
class Index(Expr):
    """An array element ``name[i, ...]``."""

    name: str
    index: tuple


@dataclass(frozen=True, slots=True)
class Array(Expr):
    """A whole array ``name[]`` (an argument of CALL, LAST, DEFINED, DECOMPOSE)."""

    name: str


@dataclass(frozen=True, slots=True)
class Call(Expr):
    """A built-in function call ``NAME(args)`` (upper-case name; an omitted argument is ``None``); ``bare``: written
    without parentheses (``HERE``, ``TASK``, ``NULL``)."""

    name: str
    args: tuple
    bare: bool = field(default=False, compare=False, kw_only=True)


@dataclass(frozen=True, slots=True)
class Fmt(Expr):
    """An output format ``/F8.3`` in an output list (``spec`` is ``F8.3``)."""

    spec: str


@dataclass(frozen=True, slots=True)
class Unary(Expr):
    op: str            # -, NOT, COM
    operand: Expr


@dataclass(frozen=True, slots=True)
class BinOp(Expr):
    op: str            # + - * / ^ MOD AND OR XOR BAND BOR BXOR == <> < > <= >= :
    left: Expr
    right: Expr


@dataclass(frozen=True, slots=True)
class Shift(Expr):
    """``SHIFT(base BY dx, dy, dz)``; an omitted component is ``None``."""

    base: Expr
    deltas: tuple


@dataclass(frozen=True, slots=True)
class Paren(Expr):
    """A variable in parentheses as a CALL argument, ``(x)``: passed by value."""

    expr: Expr


# -- statements -----------------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class Stmt(Node):
    """A statement (one program line)."""


@dataclass(frozen=True, slots=True)
class Nop(Stmt):
    """An empty statement."""


@dataclass(frozen=True, slots=True)
class Label(Stmt):
    """A step label, with the statement on its line (or ``None``)."""

    number: int
    stmt: Stmt | None


@dataclass(frozen=True, slots=True)
class Assign(Stmt):
    """``target = value``, or ``SET target = value`` (``is_set``)."""

    target: Expr
    value: Expr
    is_set: bool


@dataclass(frozen=True, slots=True)
class If(Stmt):
    cond: Expr


@dataclass(frozen=True, slots=True)
class IfGoto(Stmt):
    cond: Expr
    label: int


@dataclass(frozen=True, slots=True)
class Word(Stmt):
    """An instruction that is one word: ELSE, END, DO, ANY, RETURN, RETURNE, HALT, STOP, PAUSE, BREAK, BRAKE,
    NULL."""

    word: str
    colon: bool = False            # ANY:


@dataclass(frozen=True, slots=True)
class While(Stmt):
    cond: Expr


@dataclass(frozen=True, slots=True)
class Until(Stmt):
    cond: Expr


@dataclass(frozen=True, slots=True)
class For(Stmt):
    var: Expr
    start: Expr
    stop: Expr
    step: Expr | None


@dataclass(frozen=True, slots=True)
class Case(Stmt):
    expr: Expr


@dataclass(frozen=True, slots=True)
class Value(Stmt):
    values: tuple


@dataclass(frozen=True, slots=True)
class Goto(Stmt):
    label: int


@dataclass(frozen=True, slots=True)
class CallStmt(Stmt):
    """``CALL name(args)``."""

    name: str
    args: tuple
    parens: bool = False           # the argument list's parentheses were written


@dataclass(frozen=True, slots=True)
class Calls(Stmt):
    """``CALLS $name(args)``: the program named by a string."""

    target: Expr
    args: tuple
    parens: bool = False           # the argument list's parentheses were written


@dataclass(frozen=True, slots=True)
class LoopJump(Stmt):
    """``EXIT n`` or ``NEXT n``."""

    word: str
    count: int


@dataclass(frozen=True, slots=True)
class Wait(Stmt):
    cond: Expr | None


@dataclass(frozen=True, slots=True)
class Items(Stmt):
    """An instruction followed by a list of expressions (an omitted one is ``None``)."""

    items: tuple


@dataclass(frozen=True, slots=True)
class Type(Items):
    """``TYPE`` output items (expressions and formats)."""


@dataclass(frozen=True, slots=True)
class Prompt(Items):
    """``PROMPT`` output items; the variables among them are read."""


@dataclass(frozen=True, slots=True)
class Signal(Items):
    """``SIGNAL`` signal numbers (negative: off)."""


@dataclass(frozen=True, slots=True)
class Accel(Items):
    """``ACCEL [(profile)] acc, dec [ALWAYS]``."""

    always: bool = False
    profile: Expr | None = None


@dataclass(frozen=True, slots=True)
class TaskControl(Items):
    """ABORT, KILL or CYCLE.END of tasks."""

    word: str = ""


@dataclass(frozen=True, slots=True)
class Event(Items):
    """WAIT.EVENT or SET.EVENT."""

    word: str = ""


@dataclass(frozen=True, slots=True)
class Declare(Stmt):
    """AUTO, LOCAL or GLOBAL: ``names`` are ``(name, type, is_array)``, type REAL, DOUBLE, LOC, PRECISION,
    PPOINT or STRING; ``texts`` the items as written (type words and names with their dimensions), in order."""

    word: str
    names: tuple
    texts: tuple = ()


@dataclass(frozen=True, slots=True)
class IoStmt(Stmt):
    """ATTACH, DETACH, FCLOSE (the list in parentheses may be missing) or FOPEN: ``(args)`` then output items."""

    word: str
    args: tuple
    items: tuple
    parens: bool = True


@dataclass(frozen=True, slots=True)
class Write(Stmt):
    """``WRITE (lun, handle) items``."""

    args: tuple
    items: tuple


@dataclass(frozen=True, slots=True)
class DiskOpen(Stmt):
    """FOPENR, FOPENW, FOPENA, FOPEND, FDELETE ``(lun) name``."""

    word: str
    args: tuple
    items: tuple


@dataclass(frozen=True, slots=True)
class Read(Stmt):
    args: tuple
    targets: tuple


@dataclass(frozen=True, slots=True)
class Execute(Stmt):
    """``EXECUTE [/C] [task,] name(args), extra...``."""

    task: Expr | None
    name: str
    args: tuple
    extra: tuple
    switch: str | None = None      # /C: accepted, no effect
    comma: bool = False            # a comma after the task number
    parens: bool = False           # the argument list's parentheses were written


@dataclass(frozen=True, slots=True)
class Reacte(Stmt):
    name: str


@dataclass(frozen=True, slots=True)
class Robot(Stmt):
    """A motion or robot instruction with a location and maybe a second argument: MOVE, MOVES, DEPART, DEPARTS,
    DELAY, TOOL (one), APPRO, APPROS, MOVET, MOVEST (two)."""

    word: str
    loc: Expr
    arg: Expr | None = None


@dataclass(frozen=True, slots=True)
class Duration(Stmt):
    time: Expr
    always: bool


@dataclass(frozen=True, slots=True)
class Config(Stmt):
    """LEFTY, RIGHTY, ABOVE, BELOW, FLIP, NOFLIP, SINGLE, MULTIPLE."""

    word: str


@dataclass(frozen=True, slots=True)
class Speed(Stmt):
    speed: Expr
    mode: str | None               # ALWAYS, MONITOR
    rotation: Expr | None = None   # accepted, the model has one speed


@dataclass(frozen=True, slots=True)
class Here(Stmt):
    target: Expr


@dataclass(frozen=True, slots=True)
class Decompose(Stmt):
    target: Expr
    value: Expr


@dataclass(frozen=True, slots=True)
class Switch(Stmt):
    """ENABLE or DISABLE of system switches."""

    word: str
    names: tuple


@dataclass(frozen=True, slots=True)
class Hand(Stmt):
    """OPEN, OPENI, CLOSE, CLOSEI, RELAX, RELAXI with an optional hand number (accepted, one hand)."""

    word: str
    arg: Expr | None


@dataclass(frozen=True, slots=True)
class Parameter(Stmt):
    name: str
    value: Expr


@dataclass(frozen=True, slots=True)
class Select(Stmt):
    """``SELECT device = unit`` (the emulator: ROBOT)."""

    device: str
    unit: Expr


@dataclass(frozen=True, slots=True)
class Calibrate(Stmt):
    """``CALIBRATE [mode[, status]]``: ``status`` is a variable."""

    mode: Expr | None = None
    status: Expr | None = None


@dataclass(frozen=True, slots=True)
class Bits(Stmt):
    """``BITS first, count = value``."""

    first: Expr
    count: Expr | None
    value: Expr


@dataclass(frozen=True, slots=True)
class TimerSet(Stmt):
    """``TIMER n = value``."""

    timer: Expr
    value: Expr
