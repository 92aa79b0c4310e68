"""Syntax tree nodes back to V+ source text: :func:`unparse` of a statement or an expression.

The text is the source line's up to spacing and case: names in the form the emulator keeps them (lower case, 15
significant characters), numbers and constants as written, the parentheses that were written. What the parser
drops (a unary ``+``, ``()`` after a no-argument function) does not come back.
"""

from __future__ import annotations

from collections.abc import Callable

from aioadept.vplus import nodes as N


def unparse(node: N.Node | None) -> str:
    """The V+ source of ``node`` (``None``: an omitted argument, the empty text)."""
    if node is None:
        return ""
    text = _RENDER[type(node)](node)
    if isinstance(node, N.Expr) and node.parens:
        text = "(" * node.parens + text + ")" * node.parens
    return text


def _list(items: tuple, sep: str = ", ") -> str:
    return sep.join(unparse(x) for x in items)


def _call(e: N.Call) -> str:
    if e.bare:
        return e.name
    return f"{e.name}({_list(e.args)})"


def _unary(e: N.Unary) -> str:
    return f"{e.op}{unparse(e.operand)}" if e.op == "-" else f"{e.op} {unparse(e.operand)}"


def _num(e: N.Num) -> str:
    return e.text or repr(e.value)


def _declare(st: N.Declare) -> str:
    out = st.word
    sep = " "
    for text in st.texts:
        out += sep + text
        sep = " " if text.upper() in ("REAL", "DOUBLE", "LOC", "PRECISION") else ", "
    return out


def _execute(st: N.Execute) -> str:
    out = "EXECUTE"
    if st.switch:
        out += f" /{st.switch}"
    if st.task is not None:
        out += f" {unparse(st.task)}" + ("," if st.comma else "")
    out += f" {st.name}" + (f"({_list(st.args)})" if st.parens else "")
    return out + "".join(f", {unparse(x)}" for x in st.extra)


def _io(st) -> str:
    parens = getattr(st, "parens", True)
    word = st.word if hasattr(st, "word") else type(st).__name__.upper()
    out = word + (f" ({_list(st.args)})" if parens else "")
    return out + (" " + _list(st.items) if st.items else "")


def _opt(prefix: str, e: N.Node | None) -> str:
    return "" if e is None else prefix + unparse(e)


_RENDER: dict[type, Callable] = {
    # expressions
    N.Num: _num,
    N.Str: lambda e: e.value if e.bare else f'"{e.value}"',
    N.Name: lambda e: e.name,
    N.Index: lambda e: f"{e.name}[{_list(e.index)}]",
    N.Array: lambda e: f"{e.name}[]",
    N.Call: _call,
    N.Fmt: lambda e: f"/{e.spec}",
    N.Unary: _unary,
    N.BinOp: lambda e: f"{unparse(e.left)} {e.op} {unparse(e.right)}",
    N.Shift: lambda e: f"SHIFT({unparse(e.base)} BY {_list(e.deltas)})",
    N.Paren: lambda e: unparse(e.expr),
    # statements
    N.Nop: lambda st: "",
    N.Label: lambda st: f"{st.number}" + _opt(" ", st.stmt),
    N.Assign: lambda st: ("SET " if st.is_set else "") + f"{unparse(st.target)} = {unparse(st.value)}",
    N.If: lambda st: f"IF {unparse(st.cond)} THEN",
    N.IfGoto: lambda st: f"IF {unparse(st.cond)} GOTO {st.label}",
    N.Word: lambda st: st.word + (":" if st.colon else ""),
    N.While: lambda st: f"WHILE {unparse(st.cond)} DO",
    N.Until: lambda st: f"UNTIL {unparse(st.cond)}",
    N.For: lambda st: f"FOR {unparse(st.var)} = {unparse(st.start)} TO {unparse(st.stop)}" + _opt(" STEP ", st.step),
    N.Case: lambda st: f"CASE {unparse(st.expr)} OF",
    N.Value: lambda st: f"VALUE {_list(st.values)}:",
    N.Goto: lambda st: f"GOTO {st.label}",
    N.CallStmt: lambda st: f"CALL {st.name}" + (f"({_list(st.args)})" if st.parens else ""),
    N.Calls: lambda st: f"CALLS {unparse(st.target)}" + (f"({_list(st.args)})" if st.parens else ""),
    N.LoopJump: lambda st: st.word + ("" if st.count == 1 else f" {st.count}"),
    N.Wait: lambda st: "WAIT" + _opt(" ", st.cond),
    N.Type: lambda st: ("TYPE " + _list(st.items)).rstrip(),
    N.Prompt: lambda st: ("PROMPT " + _list(st.items)).rstrip(),
    N.Signal: lambda st: "SIGNAL " + _list(st.items),
    N.Accel: lambda st: "ACCEL " + _opt("(", st.profile) + (") " if st.profile is not None else "") + _list(st.items)
    + (" ALWAYS" if st.always else ""),
    N.TaskControl: lambda st: (st.word + " " + _list(st.items)).rstrip(),
    N.Event: lambda st: (st.word + " " + _list(st.items)).rstrip(),
    N.Declare: _declare,
    N.IoStmt: _io,
    N.Write: _io,
    N.DiskOpen: _io,
    N.Read: lambda st: f"READ ({_list(st.args)})" + (" " + _list(st.targets) if st.targets else ""),
    N.Execute: _execute,
    N.Reacte: lambda st: f"REACTE {st.name}",
    N.Robot: lambda st: f"{st.word} {unparse(st.loc)}" + _opt(", ", st.arg),
    N.Duration: lambda st: f"DURATION {unparse(st.time)}" + (" ALWAYS" if st.always else ""),
    N.Config: lambda st: st.word,
    N.Speed: lambda st: f"SPEED {unparse(st.speed)}" + _opt(", ", st.rotation) + (f" {st.mode}" if st.mode else ""),
    N.Here: lambda st: f"HERE {unparse(st.target)}",
    N.Decompose: lambda st: f"DECOMPOSE {unparse(st.target)} = {unparse(st.value)}",
    N.Switch: lambda st: f"{st.word} {', '.join(st.names)}",
    N.Hand: lambda st: st.word + _opt(" ", st.arg),
    N.Parameter: lambda st: f"PARAMETER {st.name} = {unparse(st.value)}",
    N.Select: lambda st: f"SELECT {st.device} = {unparse(st.unit)}",
    N.Calibrate: lambda st: ("CALIBRATE" + _opt(" ", st.mode) + _opt(", ", st.status)).replace("CALIBRATE, ",
                                                                                                  "CALIBRATE , "),
    N.Bits: lambda st: f"BITS {unparse(st.first)}" + _opt(", ", st.count) + f" = {unparse(st.value)}",
    N.TimerSet: lambda st: f"TIMER {unparse(st.timer)} = {unparse(st.value)}",
}
