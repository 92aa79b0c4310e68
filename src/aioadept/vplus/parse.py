"""V+ source text to syntax trees: the tokenizer, the expression parser and the statement parser.

One line of a ``.PROGRAM`` body in, one :mod:`~aioadept.vplus.nodes` statement out, each node with its span;
:mod:`aioadept.vplus.compiler` turns the statements of a program into Python. Nothing here runs code or knows
about tasks. Statements are parsed by a table, :data:`STATEMENTS`, from the leading keyword to a small function.

Names are case-insensitive and only their first 15 characters count (V+ Language User's Guide, "Variable Name
Requirements": longer names are truncated without warning); :func:`norm` does both. ``$`` (string) and ``#``
(precision point) prefixes are part of the name.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, replace

from aioadept.errors import AdeptError
from aioadept.vplus import keywords, registry
from aioadept.vplus import nodes as N

MAX_NAME = 15


class VSyntaxError(AdeptError):
    """A line that cannot be parsed; ``word`` is the offending token, ``col`` its 1-based column (0: unknown)."""

    def __init__(self, message: str, word: str = "", col: int = 0) -> None:
        super().__init__(message)
        self.message = message
        self.word = word
        self.col = col


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
    col: int = 0   # offset of the first character in the line's text (0-based)


def tokenize(text: str) -> list[Tok]:
    out: list[Tok] = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m:
            word = text[pos:].split()[0] if text[pos:].split() else text[pos:]
            raise VSyntaxError(f"unexpected character {text[pos]!r}", word, pos + 1)
        start, pos = pos, m.end()
        kind = m.lastgroup
        s = m.group(kind)
        if kind == "ws":
            continue
        if kind == "num":
            out.append(Tok("num", s, float(s), start))
        elif kind == "hex":
            # V+ radix constants (Language User's Guide v17 p. 102, "Numeric Representation"): ^H hexadecimal,
            # ^B binary (at most 8 bits), ^ and digits octal, ^D a double-precision integer. Right after an
            # operand, '^' is the power operator instead (x^2, a[1]^2); a word operator (x = ^B1001001 BAND
            # ^B1110011, the same page) or the instruction word that starts the line (SIGNAL ^B101) is no operand.
            prev = out[-1] if out else None
            if prev is not None and (prev.kind in ("num", "str") or prev.text in (")", "]")
                                     or (prev.kind == "name" and not _keyword_before(out))):
                out.append(Tok("op", "^", None, start))
                pos = m.start() + 1
                continue
            out.append(Tok("num", s, _radix(s, start), start))
        elif kind == "asc":
            out.append(Tok("num", s, float(ord(s[1])), start))
        elif kind == "str":
            out.append(Tok("str", s, s[1:-1], start))
        else:
            out.append(Tok(kind, s, None, start))
    return out


def _keyword_before(out: list[Tok]) -> bool:
    """The last token is a word operator, or the instruction word that starts the line (after a label)."""
    up = out[-1].text.upper()
    if up in _RESERVED_WORDS:
        return True
    first = 1 if out[0].kind == "num" else 0
    return len(out) == first + 1 and up in STATEMENTS


def _radix(s: str, start: int) -> float:
    radix = s[1].upper()
    digits, base = (s[2:], {"H": 16, "B": 2, "D": 10}[radix]) if radix in "HBD" else (s[1:], 8)
    if radix == "B" and len(digits) > 8:
        raise VSyntaxError("a binary constant has at most 8 bits", s, start + 1)
    return float(int(digits, base))


# Word operators and constants.
_CONST = {"TRUE": -1.0, "FALSE": 0.0, "ON": -1.0, "OFF": 0.0, "PI": 3.141592653589793}
_REL = {"==": "==", "<>": "<>", "<": "<", ">": ">", "<=": "<=", ">=": ">=", "=<": "<=", "=>": ">="}
_FMT_RE = re.compile(r"[A-Za-z](\d+(\.\d+)?)?\Z")


class Parser:
    """Recursive-descent parser over one line's tokens; spans are in ``file`` at ``line``, the text starting at
    column ``col0 + 1``."""

    def __init__(self, toks: list[Tok], file: str = "", line: int = 0, col0: int = 0) -> None:
        self.t = toks
        self.i = 0
        self.file, self.line, self.col0 = file, line, col0
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

    def col(self, t: Tok | None) -> int:
        """The 1-based column of token ``t`` (None: just after the line's last token)."""
        if t is None:
            last = self.t[-1] if self.t else None
            return self.col0 + (last.col + len(last.text) if last else 0) + 1
        return self.col0 + t.col + 1

    def error(self, message: str, t: Tok | None, word: str | None = None) -> VSyntaxError:
        """The error ``message`` at token ``t`` (None: at the end of the line)."""
        if word is None:
            word = t.text if t is not None else "end of line"
        return VSyntaxError(message, word, self.col(t))

    def span(self, i0: int) -> N.Span:
        """The span of tokens ``i0`` up to the last one taken."""
        if not self.t:
            return N.Span(self.file, self.line, self.col0 + 1, self.col0 + 1)
        a = self.t[min(i0, len(self.t) - 1)]
        b = self.t[max(self.i - 1, i0)] if self.i > i0 else a
        return N.Span(self.file, self.line, self.col(a), self.col(b) + len(b.text))

    def take(self) -> Tok:
        t = self.peek()
        if t is None:
            raise self.error("unexpected end of line", None, "")
        self.i += 1
        return t

    def expect_op(self, op: str) -> None:
        t = self.peek()
        if t is None or t.kind != "op" or t.text != op:
            raise self.error(f"expected {op!r}", t)
        self.i += 1

    def expect_word(self, w: str) -> None:
        if not self.at_word(w):
            raise self.error(f"expected {w}", self.peek())
        self.i += 1

    def done(self) -> bool:
        return self.i >= len(self.t)

    def expect_end(self) -> None:
        if not self.done():
            t = self.peek()
            raise self.error(f"unexpected {t.text!r}", t)

    # -- expressions (lowest precedence first) ------------------------------------------------------------
    def _binary(self, i0: int, op: str, a: N.Expr, b: N.Expr) -> N.BinOp:
        return N.BinOp(op, a, b, span=self.span(i0))

    def expr(self) -> N.Expr:
        i0 = self.i
        a = self._and()
        while self.at_word("OR", "XOR"):
            op = self.take().text.upper()
            a = self._binary(i0, op, a, self._and())
        return a

    def _and(self) -> N.Expr:
        i0 = self.i
        a = self._not()
        while self.at_word("AND"):
            self.take()
            a = self._binary(i0, "AND", a, self._not())
        return a

    def _not(self) -> N.Expr:
        if self.at_word("NOT"):
            i0 = self.i
            self.take()
            e = self._not()
            return N.Unary("NOT", e, span=self.span(i0))
        return self._rel()

    def _rel(self) -> N.Expr:
        i0 = self.i
        a = self._bor()
        t = self.peek()
        if t is not None and t.kind == "op" and t.text in _REL:
            self.take()
            a = self._binary(i0, _REL[t.text], a, self._bor())
        elif t is not None and t.kind == "op" and t.text == "=" and not self.eq_ends:
            raise self.error("'=' in an expression (comparison is '==')", t)
        return a

    def _bor(self) -> N.Expr:
        i0 = self.i
        a = self._band()
        while self.at_word("BOR", "BXOR"):
            op = self.take().text.upper()
            a = self._binary(i0, op, a, self._band())
        return a

    def _band(self) -> N.Expr:
        i0 = self.i
        a = self._add()
        while self.at_word("BAND"):
            self.take()
            a = self._binary(i0, "BAND", a, self._add())
        return a

    def _add(self) -> N.Expr:
        i0 = self.i
        a = self._mul()
        while self.at_op("+", "-"):
            op = self.take().text
            a = self._binary(i0, op, a, self._mul())
        return a

    def _mul(self) -> N.Expr:
        i0 = self.i
        a = self._unary()
        while self.at_op("*", "/") or self.at_word("MOD"):
            op = self.take().text.upper()
            a = self._binary(i0, op, a, self._unary())
        return a

    def _unary(self) -> N.Expr:
        i0 = self.i
        if self.at_op("-") or self.at_word("COM"):
            op = self.take().text.upper()
            e = self._unary()
            return N.Unary(op, e, span=self.span(i0))
        if self.at_op("+"):
            self.take()
            return self._unary()        # a unary '+' changes nothing (rendered back without it)
        return self._pow()

    def _pow(self) -> N.Expr:
        i0 = self.i
        a = self._compound()
        if self.at_op("^"):
            self.take()
            a = self._binary(i0, "^", a, self._unary())
        return a

    def _compound(self) -> N.Expr:
        i0 = self.i
        a = self.atom()
        while self.at_op(":") and not self.no_colon:
            self.take()
            a = self._binary(i0, ":", a, self.atom())
        return a

    def slots(self, item: Callable[[], N.Expr] | None = None) -> tuple:
        """``( e, e, ... )``: expressions or empty slots (``None``); ``item`` parses one (default :meth:`expr`)."""
        item = item or self.expr
        self.expect_op("(")
        out: list = []
        if self.at_op(")"):
            self.take()
            return ()
        while True:
            out.append(None if self.at_op(",", ")") else item())
            if self.at_op(","):
                self.take()
                continue
            self.expect_op(")")
            return tuple(out)

    def output_item(self) -> N.Expr:
        """An expression or a ``/format`` (output lists of TYPE, WRITE, $ENCODE...)."""
        return self.fmt() if self.at_op("/") else self.expr()

    def fmt(self) -> N.Fmt:
        i0 = self.i
        self.expect_op("/")
        t = self.take()
        if t.kind != "name" or not _FMT_RE.match(t.text):
            raise self.error("bad format specifier", t, "/" + t.text)
        return N.Fmt(t.text.upper(), span=self.span(i0))

    def names_index(self) -> tuple:
        """``[e, e...]`` after an array name ('[' taken)."""
        idx = [self.expr()]
        while self.at_op(","):
            self.take()
            idx.append(self.expr())
        self.expect_op("]")
        return tuple(idx)

    def atom(self) -> N.Expr:
        i0 = self.i
        t = self.take()
        if t.kind == "num":
            return N.Num(t.value, text=t.text, span=self.span(i0))
        if t.kind == "str":
            return N.Str(t.value, span=self.span(i0))
        if t.kind == "op" and t.text == "(":
            e = self.expr()
            self.expect_op(")")
            return replace(e, parens=e.parens + 1, span=self.span(i0))
        if t.kind == "name":
            return self._named(t, i0)
        raise self.error(f"unexpected {t.text!r}", t)

    def _named(self, t: Tok, i0: int) -> N.Expr:
        """An atom that starts with a name: a constant, a function call, an array element or a variable."""
        up = t.text.upper()
        if up in _CONST:
            return N.Num(_CONST[up], text=t.text, span=self.span(i0))
        if up == "NULL" and not self.at_op("(", "["):
            return N.Call("NULL", (), bare=True, span=self.span(i0))          # the null transformation (TOOL NULL)
        if up in _SPECIAL_ATOMS and self.at_op("("):
            return _SPECIAL_ATOMS[up](self, i0)
        if self.at_op("(") and up in FUNCTIONS:
            args = self.slots(self.output_item if up == "$ENCODE" else None)
            return N.Call(up, args, span=self.span(i0))
        if self.at_op("["):
            self.take()
            if self.at_op("]"):
                self.take()
                return N.Array(norm(t.text), span=self.span(i0))
            return N.Index(norm(t.text), self.names_index(), span=self.span(i0))
        if up in _NOARG_FUNCS:
            return N.Call(up, (), bare=True, span=self.span(i0))
        if self.at_op("("):
            raise _unknown_function(t.text, self.col(t))
        if t.text.upper() in _RESERVED_WORDS:
            raise self.error(f"keyword {t.text.upper()} used as a name", t)
        return N.Name(norm(t.text), span=self.span(i0))

    def lvalue(self) -> N.Expr:
        """A variable, array element or array (``a[]``) that can be assigned."""
        t = self.peek()
        if t is None or t.kind != "name":
            raise self.error("expected a variable", t)
        e = self.atom()
        if not isinstance(e, (N.Name, N.Index, N.Array)):
            raise self.error("expected a variable", t)
        return e


def _shift(p: Parser, i0: int) -> N.Expr:
    """SHIFT(a BY x, y, z): an omitted component is 0 (SHIFT(a BY , , 10))."""
    p.take()
    base = p.expr()
    p.expect_word("BY")
    d: list = []
    while True:
        d.append(None if p.at_op(",", ")") else p.expr())
        if not p.at_op(","):
            break
        p.take()
    p.expect_op(")")
    return N.Shift(base, tuple(d), span=p.span(i0))


def _switch_fn(p: Parser, i0: int) -> N.Expr:
    """SWITCH(name): the argument names a system switch (POWER, DRY.RUN), it is not a variable."""
    p.take()
    j = p.i
    arg = p.take()
    if arg.kind != "name":
        raise p.error("SWITCH needs a switch name", arg)
    name = N.Str(arg.text.upper(), bare=True, span=p.span(j))
    p.expect_op(")")
    return N.Call("SWITCH", (name,), span=p.span(i0))


def _named_fn(fn: str, names: frozenset[str]) -> Callable[[Parser, int], N.Expr]:
    """``FN(name)`` whose argument names a system parameter or device, not a variable: PARAMETER(HAND.TIME),
    SELECT(ROBOT). A name the emulator does not have is refused at load, saying so."""

    def parse(p: Parser, i0: int) -> N.Expr:
        p.take()
        j = p.i
        arg = p.take()
        if arg.kind != "name":
            raise p.error(f"{fn} needs a name", arg)
        if arg.text.upper() not in names:
            raise p.error(f"{fn}({arg.text.upper()}) is not implemented by the emulator (it has "
                          f"{', '.join(sorted(names))})", arg)
        name = N.Str(arg.text.upper(), bare=True, span=p.span(j))
        p.expect_op(")")
        return N.Call(fn, (name,), span=p.span(i0))
    return parse


# Functions with their own argument syntax.
_SPECIAL_ATOMS: dict[str, Callable[[Parser, int], N.Expr]] = {
    "SHIFT": _shift, "SWITCH": _switch_fn,
    "PARAMETER": _named_fn("PARAMETER", frozenset({"HAND.TIME", "NOT.CALIBRATED"})),
    "SELECT": _named_fn("SELECT", frozenset({"ROBOT"})),
}

FUNCTIONS = frozenset(name for name, entry in registry.FUNCTIONS.items() if entry.call)
"""The functions ``NAME(`` calls: those the registry (:mod:`aioadept.vplus.registry`) has."""
_NOARG_FUNCS = {"HERE", "#HERE", "RANDOM", "TASK"}
_RESERVED_WORDS = {"AND", "OR", "XOR", "NOT", "MOD", "BAND", "BOR", "BXOR", "COM", "THEN", "DO", "TO", "STEP",
                   "OF", "BY", "ALWAYS", "GOTO"}


# -- statements -----------------------------------------------------------------------------------------------

def parse_statement(text: str, file: str = "", line: int = 0, col0: int = 0) -> N.Stmt:
    """One source line (comment removed, not empty) to a statement node; raises :class:`VSyntaxError`.

    ``file`` and ``line`` go into the spans; ``col0`` is how many characters of the line precede ``text``.
    """
    try:
        toks = tokenize(text)
    except VSyntaxError as exc:
        raise VSyntaxError(exc.message, exc.word, col0 + exc.col) from None
    p = Parser(toks, file, line, col0)
    if toks and toks[0].kind == "num" and re.fullmatch(r"\d+", toks[0].text):
        label = _label(p, p.take())
        inner = None if p.done() else _statement(p, 1)
        p.expect_end()
        return N.Label(label, inner, span=p.span(0))
    stmt = _statement(p, 0)
    p.expect_end()
    return stmt


MAX_LABEL = 65535


def _label(p: Parser, tok: Tok) -> int:
    """A step label: an integer 0 to 65535 (V+ Language User's Guide v17, p. 35, "Program Lines")."""
    if tok.kind != "num" or not re.fullmatch(r"\d+", tok.text):
        raise p.error("expected a label number (an integer 0 to 65535)", tok)
    n = int(tok.text)
    if n > MAX_LABEL:
        raise p.error(f"label {n} is outside 0 to {MAX_LABEL}", tok)
    return n


def _statement(p: Parser, i0: int) -> N.Stmt:
    """The statement at token ``i0``: an assignment, or the table's function for its keyword."""
    t = p.peek()
    if t is None:
        return N.Nop(span=p.span(i0))
    if t.kind != "name":
        raise p.error(f"unexpected {t.text!r}", t)
    w = t.text.upper()
    nxt = p.peek(1)
    # An assignment: name = ..., name[...] = ... (a name may look like an instruction only if followed by '=')
    if w != "SET" and nxt is not None and nxt.kind == "op" and nxt.text in ("=", "["):
        if w not in ("DECOMPOSE", "TIMER") and not (w in STATEMENTS and nxt.text == "["):
            target = p.lvalue()
            p.expect_op("=")
            return N.Assign(target, p.expr(), False, span=p.span(i0))
    parse = STATEMENTS.get(w)
    if parse is None:
        raise _unknown_instruction(t.text, p.col(t))
    p.take()
    return replace(parse(p, w), span=p.span(i0))


def _exprs(p: Parser) -> tuple:
    out = [p.expr()]
    while p.at_op(","):
        p.take()
        out.append(p.expr())
    return tuple(out)


def _outputs(p: Parser) -> tuple:
    """Output items of TYPE/WRITE/FOPEN/PROMPT: expressions and /formats, comma-separated."""
    out: list = []
    if p.done():
        return ()
    while True:
        out.append(p.output_item())
        if p.at_op(","):
            p.take()
            continue
        return tuple(out)


def _outputs_or_empty(p: Parser) -> tuple:
    """Expressions where a missing one is ``None`` (WAIT.EVENT , 1)."""
    out: list = []
    while not p.done():
        if p.at_op(","):
            out.append(None)
            p.take()
            continue
        out.append(p.expr())
        if p.at_op(","):
            p.take()
    return tuple(out)


def _call_args(p: Parser) -> tuple:
    """The argument list of CALL/CALLS: as :meth:`Parser.slots`, but a variable in parentheses, ``(x)``, is
    :class:`~aioadept.vplus.nodes.Paren`: V+ passes it by value (V+ Language User's Guide v17, p. 44, "Call by
    Value")."""
    return tuple(N.Paren(a, span=a.span) if isinstance(a, (N.Name, N.Index)) and a.parens else a
                 for a in p.slots())


def _program_name(p: Parser) -> str:
    t = p.take()
    if t.kind != "name":
        raise p.error("expected a program name", t)
    return norm(t.text)


# One function per statement keyword: (parser after the keyword, the keyword) -> node without its span.

def _set(p: Parser, w: str) -> N.Stmt:
    target = p.lvalue()
    p.expect_op("=")
    return N.Assign(target, p.expr(), True)


def _if(p: Parser, w: str) -> N.Stmt:
    cond = p.expr()
    if p.at_word("THEN"):
        p.take()
        return N.If(cond)
    if p.at_word("GOTO"):
        p.take()
        return N.IfGoto(cond, _label(p, p.take()))
    raise p.error("IF without THEN", p.peek())


def _word(p: Parser, w: str) -> N.Stmt:
    colon = w == "ANY" and p.at_op(":")
    if colon:
        p.take()
    return N.Word(w, colon)


def _while(p: Parser, w: str) -> N.Stmt:
    cond = p.expr()
    p.expect_word("DO")
    return N.While(cond)


def _until(p: Parser, w: str) -> N.Stmt:
    return N.Until(p.expr())


def _for(p: Parser, w: str) -> N.Stmt:
    var = p.lvalue()
    p.expect_op("=")
    start = p.expr()
    p.expect_word("TO")
    stop = p.expr()
    step = None
    if p.at_word("STEP"):
        p.take()
        step = p.expr()
    return N.For(var, start, stop, step)


def _case(p: Parser, w: str) -> N.Stmt:
    e = p.expr()
    p.expect_word("OF")
    return N.Case(e)


def _value(p: Parser, w: str) -> N.Stmt:
    p.no_colon = True
    vals = _exprs(p)
    p.expect_op(":")
    return N.Value(vals)


def _goto(p: Parser, w: str) -> N.Stmt:
    return N.Goto(_label(p, p.take()))


def _call(p: Parser, w: str) -> N.Stmt:
    name = _program_name(p)
    parens = p.at_op("(")
    return N.CallStmt(name, _call_args(p) if parens else (), parens)


def _calls(p: Parser, w: str) -> N.Stmt:
    i0 = p.i
    t = p.take()
    if t.kind == "str":
        e: N.Expr = N.Str(t.value, span=p.span(i0))
    elif t.kind == "name" and t.text.startswith("$"):
        e = N.Name(norm(t.text), span=p.span(i0))
        if p.at_op("["):
            p.take()
            e = N.Index(e.name, p.names_index(), span=p.span(i0))
    else:
        raise p.error("CALLS needs a string variable", t)
    parens = p.at_op("(")
    return N.Calls(e, _call_args(p) if parens else (), parens)


def _loop_jump(p: Parser, w: str) -> N.Stmt:
    return N.LoopJump(w, 1 if p.done() else int(p.take().value or 1))


def _wait(p: Parser, w: str) -> N.Stmt:
    return N.Wait(None if p.done() else p.expr())


def _event(p: Parser, w: str) -> N.Stmt:
    return N.Event(() if p.done() else _outputs_or_empty(p), w)


def _declare(p: Parser, w: str) -> N.Stmt:
    """AUTO/LOCAL/GLOBAL lists: (name, type, is_array), type 'REAL', 'DOUBLE', 'LOC', 'PPOINT', 'STRING'."""
    out, texts = [], []
    typ = "REAL"
    while not p.done():
        t = p.take()
        if t.kind != "name":
            raise p.error("expected a variable name", t)
        up = t.text.upper()
        texts.append(t.text)
        if up in ("REAL", "DOUBLE", "LOC", "PRECISION"):
            typ = up
            continue
        name = norm(t.text)
        is_arr = p.at_op("[")
        if is_arr:
            texts[-1] += _skip_dimensions(p)
        kind = "STRING" if name.startswith("$") else ("PPOINT" if name.startswith("#") else typ)
        out.append((name, kind, is_arr))
        if p.at_op(","):
            p.take()     # the type applies to every name after it (AUTO DOUBLE a, b)
    return N.Declare(w, tuple(out), tuple(texts))


def _skip_dimensions(p: Parser) -> str:
    """``[...]`` after a declared name (the dimensions: not used), as written."""
    text = p.take().text
    depth = 1
    while depth:
        x = p.take()
        text += x.text
        if x.kind == "op" and x.text == "[":
            depth += 1
        elif x.kind == "op" and x.text == "]":
            depth -= 1
    return text


def _type(p: Parser, w: str) -> N.Stmt:
    return N.Type(_outputs(p))


def _prompt(p: Parser, w: str) -> N.Stmt:
    return N.Prompt(_outputs(p))


def _signal(p: Parser, w: str) -> N.Stmt:
    return N.Signal(_exprs(p))


def _attach(p: Parser, w: str) -> N.Stmt:
    parens = p.at_op("(")
    args = p.slots() if parens else ()
    return N.IoStmt(w, args, _outputs(p), parens)


def _fopen(p: Parser, w: str) -> N.Stmt:
    args = p.slots()
    return N.IoStmt(w, args, _outputs(p))


def _read(p: Parser, w: str) -> N.Stmt:
    args = p.slots()
    targets = []
    if not p.done():
        targets.append(p.lvalue())
        while p.at_op(","):
            p.take()
            targets.append(p.lvalue())
    return N.Read(args, tuple(targets))


def _write(p: Parser, w: str) -> N.Stmt:
    args = p.slots()
    return N.Write(args, _outputs(p))


def _execute(p: Parser, w: str) -> N.Stmt:
    task, switch = None, None
    if p.at_op("/"):
        switch = p.fmt().spec          # /C etc.: accepted, no effect
    if p.peek() is not None and p.peek().kind == "num":
        i0 = p.i
        t = p.take()
        task = N.Num(t.value, text=t.text, span=p.span(i0))
    comma = p.at_op(",")
    if comma:
        p.take()
    name = _program_name(p)
    parens = p.at_op("(")
    args = _call_args(p) if parens else ()
    extra = []
    while p.at_op(","):
        p.take()
        extra.append(None if p.at_op(",") or p.done() else p.expr())
    return N.Execute(task, name, args, tuple(extra), switch, comma, parens)


def _task_control(p: Parser, w: str) -> N.Stmt:
    return N.TaskControl(() if p.done() else _exprs(p), w)


def _reacte(p: Parser, w: str) -> N.Stmt:
    return N.Reacte(norm(p.take().text))


def _robot1(p: Parser, w: str) -> N.Stmt:
    return N.Robot(w, p.expr())


def _robot2(p: Parser, w: str) -> N.Stmt:
    loc = p.expr()
    p.expect_op(",")
    return N.Robot(w, loc, p.expr())


def _duration(p: Parser, w: str) -> N.Stmt:
    e = p.expr()
    always = p.at_word("ALWAYS")
    if always:
        p.take()
    return N.Duration(e, always)


def _config(p: Parser, w: str) -> N.Stmt:
    return N.Config(w)


def _disk_open(p: Parser, w: str) -> N.Stmt:
    args = p.slots()
    return N.DiskOpen(w, args, _outputs(p))


def _speed(p: Parser, w: str) -> N.Stmt:
    e = p.expr()
    mode, rot = None, None
    if p.at_op(","):
        p.take()
        rot = p.expr()        # rotational speed: accepted, the model has one speed
    if p.at_word("MMPS", "IPS"):
        raise p.error(f"SPEED ... {p.peek().text.upper()} is not implemented by the emulator (its speeds are "
                      "percent of the maximum)", p.peek())
    if p.at_word("ALWAYS", "MONITOR"):
        mode = p.take().text.upper()
    return N.Speed(e, mode, rot)


def _accel(p: Parser, w: str) -> N.Stmt:
    # ACCEL (profile) acceleration, deceleration: a parenthesised value followed by another value is the profile
    # (V+ Language Reference Guide, ACCEL); followed by nothing, ',' or an operator it is the acceleration itself
    profile = None
    if p.at_op("("):
        i0 = p.i
        p.take()
        e = p.expr()
        p.expect_op(")")
        nxt = p.peek()
        if nxt is not None and (nxt.kind != "op" or nxt.text == "(") and nxt.text.upper() not in _INFIX_WORDS:
            profile = e
        else:
            p.i = i0
    e = _exprs(p)
    always = p.at_word("ALWAYS")
    if always:
        p.take()
    return N.Accel(e, always, profile)


_INFIX_WORDS = {"AND", "OR", "XOR", "BAND", "BOR", "BXOR", "MOD", "ALWAYS"}


def _select(p: Parser, w: str) -> N.Stmt:
    """SELECT ROBOT = unit: the robot the task's motion instructions drive (the emulator has robot 1)."""
    dev = p.take()
    if dev.kind != "name":
        raise p.error("expected a device name (SELECT ROBOT = unit)", dev)
    if dev.text.upper() != "ROBOT":
        raise p.error(f"SELECT {dev.text.upper()} is not implemented by the emulator (it has SELECT ROBOT)", dev)
    p.expect_op("=")
    return N.Select("ROBOT", p.expr())


def _calibrate(p: Parser, w: str) -> N.Stmt:
    """CALIBRATE [mode[, status]]: ``status`` is a variable that receives the outcome."""
    mode = None if p.done() or p.at_op(",") else p.expr()
    status = None
    if p.at_op(","):
        p.take()
        status = p.lvalue()
    return N.Calibrate(mode, status)


def _here(p: Parser, w: str) -> N.Stmt:
    return N.Here(p.lvalue())


def _decompose(p: Parser, w: str) -> N.Stmt:
    target = p.lvalue()
    p.expect_op("=")
    return N.Decompose(target, p.expr())


def _switch(p: Parser, w: str) -> N.Stmt:
    names = []
    while not p.done():
        names.append(p.take().text.upper())
        if p.at_op(","):
            p.take()
    return N.Switch(w, tuple(names))


def _hand(p: Parser, w: str) -> N.Stmt:
    # An optional hand number (or a servo hand's opening): accepted, the model has one pneumatic hand.
    return N.Hand(w, None if p.done() else p.expr())


def _parameter(p: Parser, w: str) -> N.Stmt:
    name = p.take()
    if name.kind != "name":
        raise p.error("expected a parameter name", name)
    p.expect_op("=")
    return N.Parameter(name.text.upper(), p.expr())


def _bits(p: Parser, w: str) -> N.Stmt:
    p.eq_ends = True
    first = p.expr()
    count = None
    if p.at_op(","):
        p.take()
        count = p.expr()
    p.expect_op("=")
    p.eq_ends = False
    return N.Bits(first, count, p.expr())


def _timer(p: Parser, w: str) -> N.Stmt:
    # TIMER timer_number = time_value: the '=' ends the number's expression (as in BITS)
    p.eq_ends = True
    n = p.expr()
    p.eq_ends = False
    p.expect_op("=")
    return N.TimerSet(n, p.expr())


CONFIG_INSTRUCTIONS = ("LEFTY", "RIGHTY", "ABOVE", "BELOW", "FLIP", "NOFLIP", "SINGLE", "MULTIPLE")
HAND_INSTRUCTIONS = ("OPEN", "OPENI", "CLOSE", "CLOSEI", "RELAX", "RELAXI")


def _table(*groups: tuple[str, Callable[[Parser, str], N.Stmt]]) -> dict[str, Callable[[Parser, str], N.Stmt]]:
    return {w: fn for words, fn in groups for w in words.split()}


STATEMENTS = _table(
    ("SET", _set), ("IF", _if), ("WHILE", _while), ("UNTIL", _until), ("FOR", _for), ("CASE", _case),
    ("ELSE END DO ANY RETURN RETURNE HALT STOP PAUSE BREAK BRAKE NULL", _word),
    ("VALUE", _value), ("GOTO", _goto), ("CALL", _call), ("CALLS", _calls), ("EXIT NEXT", _loop_jump),
    ("WAIT", _wait), ("WAIT.EVENT SET.EVENT", _event), ("AUTO LOCAL GLOBAL", _declare),
    ("TYPE", _type), ("PROMPT", _prompt), ("SIGNAL", _signal), ("ATTACH DETACH FCLOSE", _attach),
    ("FOPEN FCMND", _fopen), ("READ", _read), ("WRITE", _write), ("EXECUTE", _execute),
    ("ABORT KILL CYCLE.END", _task_control), ("REACTE", _reacte),
    ("MOVE MOVES TOOL DEPART DEPARTS DELAY", _robot1), ("APPRO APPROS MOVET MOVEST", _robot2),
    ("DURATION", _duration), (" ".join(CONFIG_INSTRUCTIONS), _config),
    ("FOPENR FOPENW FOPENA FOPEND FDELETE", _disk_open), ("SPEED", _speed), ("ACCEL", _accel),
    ("HERE", _here), ("DECOMPOSE", _decompose), ("ENABLE DISABLE", _switch),
    (" ".join(HAND_INSTRUCTIONS), _hand), ("PARAMETER", _parameter), ("BITS", _bits), ("TIMER", _timer),
    ("SELECT", _select), ("CALIBRATE", _calibrate),
)
"""The statement parsers by leading keyword (disk files: aioadept.vplus.disk; digital I/O and the hand:
aioadept.sim.io). A keyword missing here is reported by :func:`_unknown_instruction`."""

INSTRUCTIONS = frozenset(STATEMENTS)


def _unknown_instruction(word: str, col: int = 0) -> VSyntaxError:
    """The error for a statement's first word that the emulator does not know: a typo, or a V+ gap (named)."""
    up = word.upper()
    if up in keywords.INSTRUCTIONS:
        return VSyntaxError(f"V+ instruction {up} is not implemented by the emulator "
                            f"(see {keywords.where(up)})", word, col)
    if up in keywords.MONITOR_COMMANDS:
        return VSyntaxError(f"{up} is a V+ monitor command, not a program instruction "
                            f"(see {keywords.where(up)})", word, col)
    if keywords.is_keyword(up) or up in FUNCTIONS:
        return VSyntaxError(f"syntax error: {up} is a V+ keyword but not an instruction", word, col)
    return VSyntaxError(f"syntax error: {word} is not a V+ keyword", word, col)


def _unknown_function(word: str, col: int = 0) -> VSyntaxError:
    """The error for ``name(`` in an expression where ``name`` is no function the emulator implements."""
    up = word.upper()
    if up in keywords.FUNCTIONS:
        return VSyntaxError(f"V+ function {up} is not implemented by the emulator "
                            f"(see {keywords.where(up, as_function=True)})", word, col)
    return VSyntaxError(f"syntax error: {word} is not a V+ function", word, col)
