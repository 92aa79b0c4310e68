"""Reading TOML configuration files for the command-line tools, with mistakes reported in one line.

One place for the checks every ``--config`` shares (``vision``, and the cell file of ``demo``/``focus``/
``experiment``): a missing or unreadable file, bad TOML (file, line and column), an unknown key, a value of the
wrong type (``delta_z_mm = "2.0"``). Each raises :class:`ConfigError`, a ``ValueError`` whose message names the
file, the key and what was expected; :func:`report` prints it as the one line a user sees (exit code 2, the
traceback only with ``-v``).
"""

from __future__ import annotations

import dataclasses
import sys
import tomllib
import traceback
import types
import typing
from pathlib import Path
from typing import Any

EXIT_USAGE = 2
"""Exit code of every ``aioadept`` subcommand for a usage or configuration mistake (nothing was started)."""


class ConfigError(ValueError):
    """A configuration file that cannot be used; the message is one line naming the file and what is wrong."""


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
