"""Reading TOML configuration files for the command-line tools, with mistakes reported in one line.

One place for the checks every ``--config`` shares (``vision``, and the cell file of ``demo``/``focus``/
``experiment``): a missing or unreadable file, bad TOML (file, line and column), an unknown key, a value of the
wrong type (``delta_z_mm = "2.0"``). Each raises :class:`ConfigError`, a ``ValueError`` whose message names the
file, the key and what was expected; :func:`report` prints it as the one line a user sees (exit code 2, the
traceback only with ``-v``).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import tomllib
import traceback
import types
import typing
from pathlib import Path
from typing import Any
from aioadept.errors import ConfigError

EXIT_USAGE = 2
"""Exit code of every ``aioadept`` subcommand for a usage or configuration mistake (nothing was started)."""


def load_toml(path: str | Path) -> dict[str, Any]:
    """The TOML file at ``path`` as a dict; :class:`ConfigError` for a missing/unreadable file or bad TOML."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ConfigError(f"{path}: is a folder, not a TOML file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read it: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:  # its message ends "(at line L, column C)"
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: not UTF-8 text ({exc.reason})") from None


@dataclasses.dataclass(frozen=True, slots=True)
class Range:
    """The values a number may take, written once: a dataclass field holds it (:func:`ranged`), the checks
    (:func:`check_ranges`, :meth:`check`) enforce it, and ``--help`` quotes :attr:`text`, so the two cannot disagree.

    Every bound is finite or open (``inf`` and NaN are never in a range).
    """

    lo: float
    hi: float = math.inf
    lo_open: bool = False
    """``lo`` itself is excluded (``> 0`` rather than ``>= 0``)."""
    integer: bool = False
    unit: str = ""

    @property
    def text(self) -> str:
        """The range as ``--help`` shows it: ``1..100``, ``> 0``, ``>= 1``, ``0.1..50 mm``."""
        if self.hi == math.inf:
            core = f"{'>' if self.lo_open else '>='} {self.lo:g}"
        else:
            core = f"{self.lo:g}..{self.hi:g}" if not self.lo_open else f"> {self.lo:g} and <= {self.hi:g}"
        return f"{core} {self.unit}".rstrip()

    @property
    def words(self) -> str:
        """What a value must be, for an error message: ``an integer in 1..100``, ``a number > 0``."""
        kind = "an integer" if self.integer else "a number"
        return f"{kind} {'in ' if self.hi != math.inf and not self.lo_open else ''}{self.text}"

    def contains(self, value: Any) -> bool:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return False
        if self.integer and not float(value).is_integer():
            return False
        if not math.isfinite(value):
            return False
        above = value > self.lo if self.lo_open else value >= self.lo
        return above and value <= self.hi

    def check(self, name: str, value: Any, *, sep: str = " = ") -> None:
        """ValueError ``"NAME = VALUE: expected WORDS"`` unless ``value`` is in the range (``sep=" "`` for an
        option: ``"--speed 0: expected ..."``)."""
        if not self.contains(value):
            raise ValueError(f"{name}{sep}{_show(value)}: expected {self.words}")


def ranged(default: Any, rng: Range) -> Any:
    """A dataclass field with a default and its :class:`Range` (``approach_speed: int = ranged(25, Range(1, 100))``)."""
    return dataclasses.field(default=default, metadata={"range": rng})


def range_of(cls: Any, name: str) -> Range:
    """The :class:`Range` of field ``name`` of dataclass ``cls`` (KeyError if it has none)."""
    for f in dataclasses.fields(cls):
        if f.name == name:
            return f.metadata["range"]
    raise KeyError(name)


def check_ranges(obj: Any) -> None:
    """Check every field of dataclass instance ``obj`` that has a :class:`Range` (None passes: "not set");
    ValueError ``"KEY = VALUE: expected ..."`` for the first value out of range."""
    for f in dataclasses.fields(obj):
        rng = f.metadata.get("range")
        value = getattr(obj, f.name)
        if rng is not None and value is not None:
            rng.check(f.name, value)


_WORDS = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}


def _type_name(value: Any) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string", list: "a list",
            dict: "a table"}.get(type(value), type(value).__name__)


def _matches(value: Any, hint: Any) -> tuple[bool, str]:
    """Whether ``value`` (from TOML) fits the annotation ``hint``, and what was expected in words."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):  # e.g. ``str | list[str]``: any arm will do
        arms = [a for a in typing.get_args(hint) if a is not type(None)]
        results = [_matches(value, a) for a in arms]
        return any(ok for ok, _ in results), " or ".join(w for _, w in results if w)
    if origin is list:
        (item,) = typing.get_args(hint) or (Any,)
        ok = isinstance(value, list) and all(_matches(v, item)[0] for v in value)
        return ok, "a list of strings" if item is str else "a list"
    if hint is bool:
        return isinstance(value, bool), _WORDS[bool]
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool), _WORDS[int]
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool), _WORDS[float]
    if hint is str:
        return isinstance(value, str), _WORDS[str]
    return True, ""


def check_section(typ: type, section: Any, where: str) -> dict[str, Any]:
    """Check a TOML table against the fields of dataclass ``typ``: known keys, values of the annotated type.

    ``where`` names the table in messages (e.g. ``"cell.toml [focus]"``). Returns ``section`` (ints given for
    float fields become floats); raises :class:`ConfigError`.
    """
    if not isinstance(section, dict):
        raise ConfigError(f"{where}: expected a table, got {_type_name(section)}")
    hints = typing.get_type_hints(typ)
    names = [f.name for f in dataclasses.fields(typ)]
    bad = sorted(set(section) - set(names))
    if bad:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(bad)}; expected one of {', '.join(names)}")
    out = dict(section)
    for key, value in section.items():
        ok, expected = _matches(value, hints.get(key, Any))
        if not ok:
            raise ConfigError(f"{where}: {key} = {_show(value)}: expected {expected}, got {_type_name(value)}")
        if hints.get(key) in (float, float | None) and isinstance(value, int) and not isinstance(value, bool):
            out[key] = float(value)
    return out


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace('"', '\\"') + '"'
    return repr(value)


def report(prog: str, exc: BaseException, *, verbose: bool = False) -> int:
    """Print ``exc`` as one line on stderr (``PROG: message``; the traceback first with ``verbose``); returns
    :data:`EXIT_USAGE`."""
    if verbose:
        traceback.print_exception(exc, file=sys.stderr)
    print(f"{prog}: {exc}", file=sys.stderr)
    return EXIT_USAGE
