"""The V+ functions the emulator implements: name, form, result type and manual section, in one registry.

The parser reads it (which ``NAME(`` is a call, and the "not implemented" message for the rest), the code
generator reads the result types, and a language server's hover and completion can read :func:`describe`.
An implementation that needs nothing of a run time is registered with its entry by the :func:`builtin`
decorator (:mod:`aioadept.vplus.builtins`); the others are bound per run time in ``builtins.namespace``.

Pure data; nothing here parses or runs code.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from aioadept.vplus import keywords


@dataclass(frozen=True, slots=True)
class Builtin:
    """A V+ function: ``form`` as a program writes it, ``result`` (num, str, loc, pp) and where the manual
    describes it; ``call``: ``NAME(`` parses as a call of it (False for NULL, which takes no parentheses)."""

    name: str
    form: str
    result: str
    section: str
    call: bool = True


FUNCTIONS: dict[str, Builtin] = {}
IMPLEMENTATIONS: dict[str, Callable[..., Any]] = {}


def register(name: str, form: str, result: str = "num", *, call: bool = True, section: str | None = None) -> Builtin:
    """Record the function ``name``; the section defaults to its entry in the V+ Language Reference Guide."""
    entry = Builtin(name, form, result, section or keywords.where(name, as_function=True) or "emulator extension",
                    call)
    FUNCTIONS[name] = entry
    return entry


def builtin(name: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Decorator: ``fn`` implements the registered function ``name`` (it needs no run time)."""
    if name not in FUNCTIONS:
        raise KeyError(f"{name} is not a registered V+ function")

    def bind(fn: Callable[..., Any]) -> Callable[..., Any]:
        IMPLEMENTATIONS[name] = fn
        return fn
    return bind


def describe(name: str) -> str | None:
    """Hover text of a function: ``$MID(string, first, count) -> str (V+ Language Reference Guide v17, ...)``."""
    entry = FUNCTIONS.get(name.upper())
    if entry is None:
        return None
    return f"{entry.form} -> {entry.result} ({entry.section})"


def of_result(result: str) -> frozenset[str]:
    """The names of the functions whose value has type ``result``."""
    return frozenset(n for n, b in FUNCTIONS.items() if b.result == result)


# (form, result): the functions the emulator implements, by name.
_TABLE = """
$DECODE($var, $breaks, mode) str | $ENCODE(item, ...) str | $MID($string, first, count) str | LEN($string) num
POS($string, $sub, start) num | ASC($string, index) num | $CHR(code) str | VAL($string) num | $ERROR(code) str
INT(value) num | ABS(value) num | SQRT(value) num | SQR(value) num | SIN(angle) num | COS(angle) num
TAN(angle) num | ATAN2(y, x) num | ASIN(value) num | ACOS(value) num | MAX(value, ...) num | MIN(value, ...) num
TIMER(timer) num | SIG(signal, ...) num | IOSTAT(lun, mode) num | TASK(select, task) num
ERROR(source, select) num | DEFINED(variable) num | LAST(array[]) num | INRANGE(location) num
TRANS(x, y, z, yaw, pitch, roll) loc | INVERSE(location) loc | DX(location) num | DY(location) num
DZ(location) num | DISTANCE(location, location) num | #PPOINT(j1, ..., j6) pp | SIGN(value) num
FRACT(value) num | RANDOM num | $TRUNCATE($string) str | RX(angle) loc | RY(angle) loc | RZ(angle) loc
$LEFT($string, count) str | $RIGHT($string, count) str | HERE loc | #HERE pp | SPEED(select) num
$TOUPPER($string) str | $TOLOWER($string) str | SWITCH(name) num | BITS(first, count) num | $TIME(...) str
NORM(location) num | $DEFAULT(...) str | STATE(select) num | BMASK(bit, ...) num
"""

for _item in _TABLE.strip().replace("\n", " | ").split("|"):
    _form, _result = _item.strip().rsplit(" ", 1)
    register(_form.split("(")[0], _form, _result)
register("NULL", "NULL", "loc", call=False)
register("SHIFT", "SHIFT(location BY dx, dy, dz)", "loc")
