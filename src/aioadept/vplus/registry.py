"""The V+ functions and instructions the emulator implements: name, form, result type and manual section.

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

from aioadept.vplus import keywords, summaries


@dataclass(frozen=True, slots=True)
class Builtin:
    """A V+ function: ``form`` as a program writes it, ``result`` (num, str, loc, pp) and where the manual
    describes it; ``call``: ``NAME(`` parses as a call of it (False for NULL, which takes no parentheses);
    ``summary``: what it does, in one line (:mod:`aioadept.vplus.summaries`)."""

    name: str
    form: str
    result: str
    section: str
    call: bool = True
    summary: str = ""


FUNCTIONS: dict[str, Builtin] = {}
INSTRUCTIONS: dict[str, Builtin] = {}
"""The program instructions by keyword (result ``""``); the parser's table (``parse.STATEMENTS``) has one parse
function for each, and a test holds the two to the same words."""
IMPLEMENTATIONS: dict[str, Callable[..., Any]] = {}


def register(name: str, form: str, result: str = "num", *, call: bool = True, section: str | None = None) -> Builtin:
    """Record the function ``name``; the section defaults to its entry in the V+ Language Reference Guide."""
    entry = Builtin(name, form, result, section or keywords.where(name, as_function=True) or "emulator extension",
                    call, summaries.FUNCTIONS.get(name, ""))
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


def describe(name: str, *, instruction: bool = False) -> str | None:
    """Hover text: ``$MID($string, first, count) -> str (V+ Language Reference Guide v17, $MID function)`` of a
    function, ``MOVE location (..., MOVE program instruction)`` of an instruction; None if not implemented."""
    entry = (INSTRUCTIONS if instruction else FUNCTIONS).get(name.upper())
    if entry is None:
        return None
    if instruction:
        return f"{entry.form} ({entry.section})"
    return f"{entry.form} -> {entry.result} ({entry.section})"


def hover(name: str, *, instruction: bool = False) -> str | None:
    """Hover text: the form (with the result of a function), then the one-line summary and the manual section:
    ``MOVE location`` / ``Moves the robot ... (V+ Language Reference Guide v17, MOVE program instruction)``;
    None if not implemented."""
    entry = (INSTRUCTIONS if instruction else FUNCTIONS).get(name.upper())
    if entry is None:
        return None
    form = entry.form if instruction else f"{entry.form} -> {entry.result}"
    return f"{form}\n{entry.summary} ({entry.section})".replace("\n ", "\n")


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
$INTB(value) str | INTB($string, first_char) num | $LNGB(value) str | LNGB($string, first_char) num
$FLTB(value) str | FLTB($string, first_char) num | $DBLB(value) str | DBLB($string, first_char) num
GETC(lun, mode) num | PARAMETER(name) num | SELECT(device) num | $TRANSB(location) str
TRANSB($string, first_char) loc
"""

for _item in _TABLE.strip().replace("\n", " | ").split("|"):
    _form, _result = _item.strip().rsplit(" ", 1)
    register(_form.split("(")[0], _form, _result)
register("NULL", "NULL", "loc", call=False)
register("SHIFT", "SHIFT(location BY dx, dy, dz)", "loc")

# The instructions' forms ([...] optional, ... repeated).
_INSTRUCTION_TABLE = """
IF condition THEN | IF condition GOTO label | ELSE | END | WHILE condition DO | DO | UNTIL condition
FOR variable = start TO stop [STEP step] | CASE value OF | VALUE value, ...: | ANY | GOTO label
CALL program([argument, ...]) | CALLS $name([argument, ...]) | RETURN | RETURNE | EXIT | NEXT
WAIT [condition] | WAIT.EVENT [mask], [timeout] | SET.EVENT [task] | HALT | STOP | PAUSE
AUTO [type] name, ... | LOCAL [type] name, ... | GLOBAL [type] name, ... | TYPE item, ... | PROMPT item, ...
SIGNAL signal, ... | ATTACH (lun, mode) device | DETACH (lun) | FCLOSE (lun) | FOPEN (lun, mode) attributes
READ (lun, handle, mode) variable, ... | WRITE (lun, handle) item, ... | FCMND (lun, command) item, ...
EXECUTE [task,] program([argument, ...]) | ABORT task | KILL task | CYCLE.END task | REACTE program
MOVE location | MOVES location | APPRO location, distance | APPROS location, distance | DEPART distance
DEPARTS distance | MOVET location, hand | MOVEST location, hand | BREAK | BRAKE | DELAY time
SPEED value [ALWAYS] | ACCEL [(profile)] acceleration, deceleration [ALWAYS] | DURATION time [ALWAYS] | TOOL transformation
HERE location | DECOMPOSE array[] = location | SET location = value | TIMER timer = time | NULL
ENABLE switch, ... | DISABLE switch, ... | PARAMETER HAND.TIME = value | BITS first, count = value
OPEN [hand] | OPENI [hand] | CLOSE [hand] | CLOSEI [hand] | RELAX [hand] | RELAXI [hand]
LEFTY | RIGHTY | ABOVE | BELOW | FLIP | NOFLIP | SINGLE | MULTIPLE | SELECT ROBOT = unit | CALIBRATE [mode[, status]]
FOPENR (lun) file | FOPENW (lun) file | FOPENA (lun) file | FOPEND (lun) folder | FDELETE (lun) file
"""

for _form in _INSTRUCTION_TABLE.strip().replace("\n", " | ").split("|"):
    _form = _form.strip()
    _word = _form.split(" ")[0].split("(")[0]
    if _word not in INSTRUCTIONS:               # IF ... GOTO is the second form of IF
        INSTRUCTIONS[_word] = Builtin(_word, _form, "", keywords.where(_word) or "emulator extension",
                                      summary=summaries.INSTRUCTIONS.get(_word, ""))
