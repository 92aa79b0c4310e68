"""V+ source text to syntax trees: the tokenizer, the expression parser and the statement parser.

(Over 500 lines because the tokenizer, the expression grammar and the statement grammar of V+ are one
recursive-descent parser whose parts call each other; split, each part would import the others.)

One line of a ``.PROGRAM`` body in, one statement tuple out; :mod:`aioadept.vplus.compiler` turns the statements
of a program into Python. Nothing here runs code or knows about tasks.

Names are case-insensitive and only their first 15 characters count (V+ Language User's Guide, "Variable Name
Requirements": longer names are truncated without warning); :func:`norm` does both. ``$`` (string) and ``#``
(precision point) prefixes are part of the name.

Expression trees are tuples:
``("num", v)``, ``("str", s)``, ``("var", name)``, ``("idx", name, [e...])``, ``("arr", name)`` (``a[]``),
``("call", NAME, [e...])``, ``("fmt", spec)`` (``/F8.3`` in output lists), ``("un", op, e)``,
``("bin", op, a, b)``, ``("shift", e, [dx, dy, dz])`` (``SHIFT(a BY x, y, z)``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from aioadept.vplus import keywords

MAX_NAME = 15


class VSyntaxError(Exception):
    """A line that cannot be parsed; ``word`` is the offending token."""

    def __init__(self, message: str, word: str = "") -> None:
        super().__init__(message)
        self.message = message
        self.word = word


def norm(name: str) -> str:
    """The V+ identity of a name: lower case, prefix kept, at most 15 significant characters."""
    name = name.lower()
    if name[:1] in ("$", "#"):
        return name[0] + name[1:1 + MAX_NAME]
    return name[:MAX_NAME]


_TOKEN = re.compile(r"""
    (?P<ws>\s+)
  | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[Ee][+-]?\d+)?)
  | (?P<hex>\^(?:[Hh][0-9A-Fa-f]+|[Bb][01]+|[Dd]\d+|[0-7]+))
  | (?P<str>"[^"]*")
  | (?P<asc>'.)
  | (?P<name>[$#]?[A-Za-z][A-Za-z0-9._]*)
  | (?P<op><>|<=|>=|=<|=>|==|[-+*/^(),\[\]<>=:])
""", re.VERBOSE)


@dataclass(frozen=True, slots=True)
class Tok:
    kind: str      # num, str, name, op
    text: str
    value: object = None


def tokenize(text: str) -> list[Tok]:
    out: list[Tok] = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m:
            word = text[pos:].split()[0] if text[pos:].split() else text[pos:]
            raise VSyntaxError(f"unexpected character {text[pos]!r}", word)
        pos = m.end()
        kind = m.lastgroup
        s = m.group(kind)
        if kind == "ws":
            continue
        if kind == "num":
            out.append(Tok("num", s, float(s)))
        elif kind == "hex":
            # V+ radix constants (Language User's Guide v17 p. 102, "Numeric Representation"): ^H hexadecimal,
            # ^B binary (at most 8 bits), ^ and digits octal, ^D a double-precision integer. Right after an
            # operand, '^' is the power operator instead (x^2, a[1]^2).
            prev = out[-1] if out else None
            if prev is not None and (prev.kind in ("num", "str", "name") or prev.text in (")", "]")):
                out.append(Tok("op", "^"))
                pos = m.start() + 1
                continue
            radix = s[1].upper()
            digits, base = (s[2:], {"H": 16, "B": 2, "D": 10}[radix]) if radix in "HBD" else (s[1:], 8)
            if radix == "B" and len(digits) > 8:
                raise VSyntaxError("a binary constant has at most 8 bits", s)
            out.append(Tok("num", s, float(int(digits, base))))
        elif kind == "asc":
            out.append(Tok("num", s, float(ord(s[1]))))
        elif kind == "str":
            out.append(Tok("str", s, s[1:-1]))
        else:
            out.append(Tok(kind, s))
    return out


# Word operators and constants.
_CONST = {"TRUE": -1.0, "FALSE": 0.0, "ON": -1.0, "OFF": 0.0, "PI": 3.141592653589793}
_REL = {"==": "==", "<>": "<>", "<": "<", ">": ">", "<=": "<=", ">=": ">=", "=<": "<=", "=>": ">="}
_FMT_RE = re.compile(r"[A-Za-z](\d+(\.\d+)?)?\Z")


class Parser:
    """Recursive-descent parser over one line's tokens."""

    def __init__(self, toks: list[Tok]) -> None:
        self.t = toks
        self.i = 0
        self.no_colon = False      # in VALUE lists ':' ends the list instead of composing
        self.eq_ends = False       # in BITS first, count = value: '=' ends the expression

    # -- helpers ------------------------------------------------------------------------------------------
    def peek(self, k: int = 0) -> Tok | None:
        j = self.i + k
        return self.t[j] if j < len(self.t) else None

    def at_op(self, *ops: str) -> bool:
        t = self.peek()
        return t is not None and t.kind == "op" and t.text in ops

    def at_word(self, *words: str) -> bool:
        t = self.peek()
        return t is not None and t.kind == "name" and t.text.upper() in words

    def take(self) -> Tok:
        t = self.peek()
        if t is None:
            raise VSyntaxError("unexpected end of line", "")
        self.i += 1
        return t

    def expect_op(self, op: str) -> None:
        t = self.peek()
        if t is None or t.kind != "op" or t.text != op:
            raise VSyntaxError(f"expected {op!r}", t.text if t else "end of line")
        self.i += 1

    def expect_word(self, w: str) -> None:
        if not self.at_word(w):
            t = self.peek()
            raise VSyntaxError(f"expected {w}", t.text if t else "end of line")
        self.i += 1

    def done(self) -> bool:
        return self.i >= len(self.t)

    def expect_end(self) -> None:
        if not self.done():
            t = self.peek()
            raise VSyntaxError(f"unexpected {t.text!r}", t.text)

    # -- expressions (lowest precedence first) ------------------------------------------------------------
    def expr(self):
        a = self._and()
        while self.at_word("OR", "XOR"):
            op = self.take().text.upper()
            a = ("bin", op, a, self._and())
        return a

    def _and(self):
        a = self._not()
        while self.at_word("AND"):
            self.take()
            a = ("bin", "AND", a, self._not())
        return a

    def _not(self):
        if self.at_word("NOT"):
            self.take()
            return ("un", "NOT", self._not())
        return self._rel()

    def _rel(self):
        a = self._bor()
        t = self.peek()
        if t is not None and t.kind == "op" and t.text in _REL:
            self.take()
            a = ("bin", _REL[t.text], a, self._bor())
        elif t is not None and t.kind == "op" and t.text == "=" and not self.eq_ends:
            raise VSyntaxError("'=' in an expression (comparison is '==')", "=")
        return a

    def _bor(self):
        a = self._band()
        while self.at_word("BOR", "BXOR"):
            op = self.take().text.upper()
            a = ("bin", op, a, self._band())
        return a

    def _band(self):
        a = self._add()
        while self.at_word("BAND"):
            self.take()
            a = ("bin", "BAND", a, self._add())
        return a

    def _add(self):
        a = self._mul()
        while self.at_op("+", "-"):
            op = self.take().text
            a = ("bin", op, a, self._mul())
        return a

    def _mul(self):
        a = self._unary()
        while self.at_op("*", "/") or self.at_word("MOD"):
            op = self.take().text.upper()
            a = ("bin", op, a, self._unary())
        return a

    def _unary(self):
        if self.at_op("-"):
            self.take()
            return ("un", "-", self._unary())
        if self.at_op("+"):
            self.take()
            return self._unary()
        if self.at_word("COM"):
            self.take()
            return ("un", "COM", self._unary())
        return self._pow()

    def _pow(self):
        a = self._compound()
        if self.at_op("^"):
            self.take()
            a = ("bin", "^", a, self._unary())
        return a

    def _compound(self):
        a = self.atom()
        while self.at_op(":") and not self.no_colon:
            self.take()
            a = ("bin", ":", a, self.atom())
        return a

    def args(self, allow_formats: bool = False) -> list:
        """``( e, e, ... )`` after a function name; empty arguments are ``None``."""
        self.expect_op("(")
        out: list = []
        if self.at_op(")"):
            self.take()
            return out
        while True:
            if self.at_op(",", ")"):
                out.append(None)
            elif allow_formats and self.at_op("/"):
                out.append(self.fmt())
            else:
                out.append(self.expr())
            if self.at_op(","):
                self.take()
                continue
            self.expect_op(")")
            return out

    def fmt(self):
        self.expect_op("/")
        t = self.take()
        if t.kind != "name" or not _FMT_RE.match(t.text):
            raise VSyntaxError("bad format specifier", "/" + t.text)
        return ("fmt", t.text.upper())

    def atom(self):
        t = self.take()
        if t.kind == "num":
            return ("num", t.value)
        if t.kind == "str":
            return ("str", t.value)
        if t.kind == "op" and t.text == "(":
            e = self.expr()
            self.expect_op(")")
            return e
        if t.kind == "name":
            up = t.text.upper()
            if up in _CONST:
                return ("num", _CONST[up])
            if up == "NULL" and not self.at_op("(", "["):
                return ("call", "NULL", [])          # the null transformation (TOOL NULL)
            if up == "SHIFT" and self.at_op("("):
                # SHIFT(a BY x, y, z): an omitted component is 0 (SHIFT(a BY , , 10))
                self.take()
                base = self.expr()
                self.expect_word("BY")
                d: list = []
                while True:
                    d.append(None if self.at_op(",", ")") else self.expr())
                    if not self.at_op(","):
                        break
                    self.take()
                self.expect_op(")")
                return ("shift", base, d)
            if up == "SWITCH" and self.at_op("("):
                # SWITCH(name): the argument names a system switch (POWER, DRY.RUN), it is not a variable
                self.take()
                arg = self.take()
                if arg.kind != "name":
                    raise VSyntaxError("SWITCH needs a switch name", arg.text)
                self.expect_op(")")
                return ("call", up, [("str", arg.text.upper())])
            if self.at_op("(") and (_is_function(up)):
                return ("call", up, self.args(allow_formats=(up == "$ENCODE")))
            if self.at_op("["):
                self.take()
                if self.at_op("]"):
                    self.take()
                    return ("arr", norm(t.text))
                idx = [self.expr()]
                while self.at_op(","):
                    self.take()
                    idx.append(self.expr())
                self.expect_op("]")
                return ("idx", norm(t.text), idx)
            if up in _NOARG_FUNCS:
                return ("call", up, [])
            if self.at_op("("):
                raise _unknown_function(t.text)
            _check_name(t.text)
            return ("var", norm(t.text))
        raise VSyntaxError(f"unexpected {t.text!r}", t.text)

    def lvalue(self):
        """A variable, array element or array (``a[]``) that can be assigned."""
        t = self.peek()
        if t is None or t.kind != "name":
            raise VSyntaxError("expected a variable", t.text if t else "end of line")
        e = self.atom()
        if e[0] not in ("var", "idx", "arr"):
            raise VSyntaxError("expected a variable", t.text)
        return e


FUNCTIONS = {
    "$DECODE", "$ENCODE", "$MID", "LEN", "POS", "ASC", "$CHR", "VAL", "$ERROR", "INT", "ABS", "SQRT", "SIN",
    "COS", "TAN", "ATAN2", "ASIN", "ACOS", "MAX", "MIN", "TIMER", "SIG", "IOSTAT", "TASK", "ERROR", "DEFINED",
    "LAST", "INRANGE", "TRANS", "INVERSE", "DX", "DY", "DZ", "DISTANCE", "#PPOINT", "SIGN", "FRACT", "RANDOM",
    "$TRUNCATE", "RX", "RY", "RZ", "SQR", "$LEFT", "$RIGHT", "HERE", "#HERE", "SPEED", "$TOUPPER", "$TOLOWER",
    "SWITCH", "BITS", "$TIME", "NORM", "$DEFAULT", "STATE",
    "BMASK",
}
_NOARG_FUNCS = {"HERE", "#HERE", "RANDOM", "TASK"}


def _is_function(up: str) -> bool:
    return up in FUNCTIONS


_RESERVED_WORDS = {"AND", "OR", "XOR", "NOT", "MOD", "BAND", "BOR", "BXOR", "COM", "THEN", "DO", "TO", "STEP",
                   "OF", "BY", "ALWAYS", "GOTO"}


def _check_name(text: str) -> None:
    if text.upper() in _RESERVED_WORDS:
        raise VSyntaxError(f"keyword {text.upper()} used as a name", text)


# -- statements -----------------------------------------------------------------------------------------------

# Statement tuples: (KIND, ...). Instructions that the emulator does not implement are rejected at load time.
INSTRUCTIONS = {
    "IF", "ELSE", "END", "WHILE", "DO", "UNTIL", "FOR", "CASE", "VALUE", "ANY", "GOTO", "CALL", "CALLS", "RETURN",
    "RETURNE", "EXIT", "NEXT", "WAIT", "WAIT.EVENT", "HALT", "STOP", "PAUSE", "AUTO", "LOCAL", "GLOBAL", "TYPE",
    "PROMPT", "SIGNAL", "ATTACH", "DETACH", "FOPEN", "FCLOSE", "READ", "WRITE", "EXECUTE", "ABORT", "KILL",
    "CYCLE.END", "REACTE", "MOVE", "MOVES", "APPRO", "APPROS", "DEPART", "DEPARTS", "BREAK", "BRAKE", "SPEED",
    "HERE", "DECOMPOSE", "TOOL", "SET", "DELAY", "ENABLE", "DISABLE", "TIMER", "SET.EVENT", "ACCEL", "NULL",
    # digital I/O and the hand (aioadept.sim.io)
    "OPEN", "OPENI", "CLOSE", "CLOSEI", "RELAX", "RELAXI", "PARAMETER", "BITS",
    # motion words of issue 20: minimum motion time, a move with the hand, the configuration of the next motion
    "DURATION", "MOVET", "MOVEST",
    "LEFTY", "RIGHTY", "ABOVE", "BELOW", "FLIP", "NOFLIP", "SINGLE", "MULTIPLE",
    # disk files (aioadept.vplus.disk)
    "FOPENR", "FOPENW", "FOPENA", "FOPEND", "FDELETE",
}
CONFIG_INSTRUCTIONS = ("LEFTY", "RIGHTY", "ABOVE", "BELOW", "FLIP", "NOFLIP", "SINGLE", "MULTIPLE")
HAND_INSTRUCTIONS = ("OPEN", "OPENI", "CLOSE", "CLOSEI", "RELAX", "RELAXI")


def parse_statement(text: str):
    """One source line (comment removed, not empty) to a statement tuple; raises :class:`VSyntaxError`."""
    toks = tokenize(text)
    label = None
    if toks and toks[0].kind == "num" and re.fullmatch(r"\d+", toks[0].text):
        label = _label(toks[0])
        toks = toks[1:]
        if not toks:
            return ("LABEL", label, None)
    p = Parser(toks)
    stmt = _statement(p)
    p.expect_end()
    if label is not None:
        return ("LABEL", label, stmt)
    return stmt


MAX_LABEL = 65535


def _label(tok: Tok) -> int:
    """A step label: an integer 0 to 65535 (V+ Language User's Guide v17, p. 35, "Program Lines")."""
    if tok.kind != "num" or not re.fullmatch(r"\d+", tok.text):
        raise VSyntaxError("expected a label number (an integer 0 to 65535)", tok.text)
    n = int(tok.text)
    if n > MAX_LABEL:
        raise VSyntaxError(f"label {n} is outside 0 to {MAX_LABEL}", tok.text)
    return n


def _exprs(p: Parser) -> list:
    out = [p.expr()]
    while p.at_op(","):
        p.take()
        out.append(p.expr())
    return out


def _outputs(p: Parser) -> list:
    """Output items of TYPE/WRITE/FOPEN/PROMPT: expressions and /formats, comma-separated."""
    out: list = []
    if p.done():
        return out
    while True:
        if p.at_op("/"):
            out.append(p.fmt())
        else:
            out.append(p.expr())
        if p.at_op(","):
            p.take()
            continue
        return out


def _paren_list(p: Parser) -> list:
    """``(a, b, c)`` of expressions or empty slots (ATTACH (), READ (lun, , 0))."""
    p.expect_op("(")
    out: list = []
    if p.at_op(")"):
        p.take()
        return out
    while True:
        if p.at_op(",", ")"):
            out.append(None)
        else:
            out.append(p.expr())
        if p.at_op(","):
            p.take()
            continue
        p.expect_op(")")
        return out


def _call_target(p: Parser):
    t = p.take()
    if t.kind != "name":
        raise VSyntaxError("expected a program name", t.text)
    args: list = []
    if p.at_op("("):
        args = _call_args(p)
    return norm(t.text), args


def _call_args(p: Parser) -> list:
    """The argument list of CALL/CALLS: as :meth:`Parser.args`, but a variable in parentheses, ``(x)``, is kept
    as ``("paren", e)``: V+ passes it by value (V+ Language User's Guide v17, p. 44, "Call by Value")."""
    start = p.i
    out = p.args()
    # mark arguments that are exactly '(' variable ')'; the token positions tell where each argument was
    depth, arg_no, toks, j = 0, 0, p.t, start + 1
    first = j
    marks = set()
    while j < p.i - 1:
        tk = toks[j]
        if tk.kind == "op" and tk.text in "([":
            depth += 1
        elif tk.kind == "op" and tk.text in ")]":
            depth -= 1
        elif tk.kind == "op" and tk.text == "," and depth == 0:
            if _parenthesised(toks, first, j):
                marks.add(arg_no)
            arg_no, first = arg_no + 1, j + 1
        j += 1
    if _parenthesised(toks, first, p.i - 1):
        marks.add(arg_no)
    return [("paren", a) if k in marks and a is not None and a[0] in ("var", "idx") else a
            for k, a in enumerate(out)]


def _parenthesised(toks: list[Tok], a: int, b: int) -> bool:
    """Tokens a..b-1 are one parenthesised group: '(' ... ')' with the first '(' closed by the last ')'."""
    if b - a < 3 or toks[a].text != "(" or toks[b - 1].text != ")" or toks[a].kind != "op":
        return False
    depth = 0
    for j in range(a, b):
        if toks[j].kind == "op" and toks[j].text == "(":
            depth += 1
        elif toks[j].kind == "op" and toks[j].text == ")":
            depth -= 1
            if depth == 0 and j != b - 1:
                return False
    return True


def _statement(p: Parser):
    t = p.peek()
    if t is None:
        return ("NOP",)
    if t.kind != "name":
        raise VSyntaxError(f"unexpected {t.text!r}", t.text)
    w = t.text.upper()
    nxt = p.peek(1)
    # An assignment: name = ..., name[...] = ... (a name may look like an instruction only if followed by '=')
    if w not in ("SET",) and nxt is not None and nxt.kind == "op" and nxt.text in ("=", "["):
        if w not in ("DECOMPOSE", "TIMER") and not (w in INSTRUCTIONS and nxt.text == "["):
            target = p.lvalue()
            p.expect_op("=")
            return ("ASSIGN", target, p.expr(), False)
    if w not in INSTRUCTIONS:
        raise _unknown_instruction(t.text)
    p.take()
    if w == "SET":
        target = p.lvalue()
        p.expect_op("=")
        return ("ASSIGN", target, p.expr(), True)
    if w == "IF":
        cond = p.expr()
        if p.at_word("THEN"):
            p.take()
            return ("IF", cond)
        if p.at_word("GOTO"):
            p.take()
            return ("IFGOTO", cond, _label(p.take()))
        t2 = p.peek()
        raise VSyntaxError("IF without THEN", t2.text if t2 else "end of line")
    if w in ("ELSE", "END", "DO", "ANY", "RETURN", "RETURNE", "HALT", "STOP", "PAUSE", "BREAK", "BRAKE", "NULL"):
        if w == "ANY" and p.at_op(":"):
            p.take()
        return (w,)
    if w == "WHILE":
        cond = p.expr()
        p.expect_word("DO")
        return ("WHILE", cond)
    if w == "UNTIL":
        return ("UNTIL", p.expr())
    if w == "FOR":
        var = p.lvalue()
        p.expect_op("=")
        start = p.expr()
        p.expect_word("TO")
        end = p.expr()
        step = None
        if p.at_word("STEP"):
            p.take()
            step = p.expr()
        return ("FOR", var, start, end, step)
    if w == "CASE":
        e = p.expr()
        p.expect_word("OF")
        return ("CASE", e)
    if w == "VALUE":
        p.no_colon = True
        vals = [p.expr()]
        while p.at_op(","):
            p.take()
            vals.append(p.expr())
        p.expect_op(":")
        return ("VALUE", vals)
    if w == "GOTO":
        return ("GOTO", _label(p.take()))
    if w == "CALL":
        name, args = _call_target(p)
        return ("CALL", name, args)
    if w == "CALLS":
        t2 = p.take()
        if t2.kind == "str":
            e = ("str", t2.value)
        elif t2.kind == "name" and t2.text.startswith("$"):
            e = ("var", norm(t2.text))
            if p.at_op("["):
                p.take()
                idx = [p.expr()]
                while p.at_op(","):
                    p.take()
                    idx.append(p.expr())
                p.expect_op("]")
                e = ("idx", e[1], idx)
        else:
            raise VSyntaxError("CALLS needs a string variable", t2.text)
        args = _call_args(p) if p.at_op("(") else []
        return ("CALLS", e, args)
    if w in ("EXIT", "NEXT"):
        n = 1
        if not p.done():
            n = int(p.take().value or 1)
        return (w, n)
    if w == "WAIT":
        return ("WAIT", None if p.done() else p.expr())
    if w == "WAIT.EVENT":
        items = [] if p.done() else _outputs_or_empty(p)
        return ("WAIT.EVENT", items)
    if w == "SET.EVENT":
        return ("SET.EVENT", [] if p.done() else _outputs_or_empty(p))
    if w in ("AUTO", "LOCAL", "GLOBAL"):
        return (w, _declarations(p))
    if w == "TYPE":
        return ("TYPE", _outputs(p))
    if w == "PROMPT":
        items = _outputs(p)
        return ("PROMPT", items)
    if w == "SIGNAL":
        return ("SIGNAL", _exprs(p))
    if w in ("ATTACH", "DETACH", "FCLOSE"):
        args = _paren_list(p) if p.at_op("(") else []
        rest = _outputs(p)
        return (w, args, rest)
    if w == "FOPEN":
        args = _paren_list(p)
        return ("FOPEN", args, _outputs(p))
    if w == "READ":
        args = _paren_list(p)
        targets = []
        if not p.done():
            targets.append(p.lvalue())
            while p.at_op(","):
                p.take()
                targets.append(p.lvalue())
        return ("READ", args, targets)
    if w == "WRITE":
        args = _paren_list(p)
        return ("WRITE", args, _outputs(p))
    if w == "EXECUTE":
        task = None
        if p.at_op("/"):
            p.fmt()          # /C etc.: accepted, no effect
        if p.peek() is not None and p.peek().kind == "num":
            task = ("num", p.take().value)
        if p.at_op(","):
            p.take()
        name, args = _call_target(p)
        extra = []
        while p.at_op(","):
            p.take()
            extra.append(None if p.at_op(",") or p.done() else p.expr())
        return ("EXECUTE", task, name, args, extra)
    if w in ("ABORT", "KILL", "CYCLE.END"):
        return (w, [] if p.done() else _exprs(p))
    if w == "REACTE":
        t2 = p.take()
        return ("REACTE", norm(t2.text))
    if w in ("MOVE", "MOVES", "TOOL", "DEPART", "DEPARTS", "DELAY"):
        return (w, p.expr())
    if w in ("APPRO", "APPROS"):
        loc = p.expr()
        p.expect_op(",")
        return (w, loc, p.expr())
    if w in ("MOVET", "MOVEST"):
        loc = p.expr()
        p.expect_op(",")
        return (w, loc, p.expr())
    if w == "DURATION":
        e = p.expr()
        always = p.at_word("ALWAYS")
        if always:
            p.take()
        return ("DURATION", e, always)
    if w in CONFIG_INSTRUCTIONS:
        return ("CONFIG", w)
    if w in ("FOPENR", "FOPENW", "FOPENA", "FOPEND", "FDELETE"):
        args = _paren_list(p)
        return ("DISKOPEN", w, args, _outputs(p))
    if w == "SPEED":
        e = p.expr()
        mode = None
        if p.at_op(","):
            p.take()
            p.expr()        # rotational speed: accepted, the model has one speed
        if p.at_word("ALWAYS", "MONITOR"):
            mode = p.take().text.upper()
        return ("SPEED", e, mode)
    if w == "ACCEL":
        e = _exprs(p)
        if p.at_word("ALWAYS"):
            p.take()
        return ("ACCEL", e)
    if w == "HERE":
        return ("HERE", p.lvalue())
    if w == "DECOMPOSE":
        target = p.lvalue()
        p.expect_op("=")
        return ("DECOMPOSE", target, p.expr())
    if w in ("ENABLE", "DISABLE"):
        names = []
        while not p.done():
            names.append(p.take().text.upper())
            if p.at_op(","):
                p.take()
        return (w, names)
    if w in HAND_INSTRUCTIONS:
        # An optional hand number (or a servo hand's opening): accepted, the model has one pneumatic hand.
        return ("HAND", w, None if p.done() else p.expr())
    if w == "PARAMETER":
        name = p.take()
        if name.kind != "name":
            raise VSyntaxError("expected a parameter name", name.text)
        p.expect_op("=")
        return ("PARAMETER", name.text.upper(), p.expr())
    if w == "BITS":
        p.eq_ends = True
        first = p.expr()
        count = None
        if p.at_op(","):
            p.take()
            count = p.expr()
        p.expect_op("=")
        p.eq_ends = False
        return ("BITS", first, count, p.expr())
    if w == "TIMER":
        # TIMER timer_number = time_value: the '=' ends the number's expression (as in BITS)
        p.eq_ends = True
        n = p.expr()
        p.eq_ends = False
        p.expect_op("=")
        return ("TIMERSET", n, p.expr())
    raise VSyntaxError(f"instruction {w} is not implemented by the emulator", t.text)  # pragma: no cover


def _unknown_instruction(word: str) -> VSyntaxError:
    """The error for a statement's first word that the emulator does not know: a typo, or a V+ gap (named)."""
    up = word.upper()
    if up in keywords.INSTRUCTIONS:
        return VSyntaxError(f"V+ instruction {up} is not implemented by the emulator "
                            f"(see {keywords.where(up)})", word)
    if up in keywords.MONITOR_COMMANDS:
        return VSyntaxError(f"{up} is a V+ monitor command, not a program instruction "
                            f"(see {keywords.where(up)})", word)
    if keywords.is_keyword(up) or up in FUNCTIONS:
        return VSyntaxError(f"syntax error: {up} is a V+ keyword but not an instruction", word)
    return VSyntaxError(f"syntax error: {word} is not a V+ keyword", word)


def _unknown_function(word: str) -> VSyntaxError:
    """The error for ``name(`` in an expression where ``name`` is no function the emulator implements."""
    up = word.upper()
    if up in keywords.FUNCTIONS:
        return VSyntaxError(f"V+ function {up} is not implemented by the emulator "
                            f"(see {keywords.where(up, as_function=True)})", word)
    return VSyntaxError(f"syntax error: {word} is not a V+ function", word)


def _outputs_or_empty(p: Parser) -> list:
    out: list = []
    while not p.done():
        if p.at_op(","):
            out.append(None)
            p.take()
            continue
        out.append(p.expr())
        if p.at_op(","):
            p.take()
    return out


def _declarations(p: Parser) -> list[tuple[str, str, bool]]:
    """AUTO/LOCAL/GLOBAL lists: [(name, type, is_array)], type 'REAL', 'DOUBLE', 'LOC', 'PPOINT', 'STRING'."""
    out = []
    typ = "REAL"
    while not p.done():
        t = p.take()
        if t.kind != "name":
            raise VSyntaxError("expected a variable name", t.text)
        up = t.text.upper()
        if up in ("REAL", "DOUBLE", "LOC", "PRECISION"):
            typ = up
            continue
        name = norm(t.text)
        is_arr = False
        if p.at_op("["):
            p.take()
            depth = 1
            while depth:
                x = p.take()
                if x.kind == "op" and x.text == "[":
                    depth += 1
                elif x.kind == "op" and x.text == "]":
                    depth -= 1
            is_arr = True
        kind = "STRING" if name.startswith("$") else ("PPOINT" if name.startswith("#") else typ)
        out.append((name, kind, is_arr))
        if p.at_op(","):
            p.take()     # the type applies to every name after it (AUTO DOUBLE a, b)
    return out
