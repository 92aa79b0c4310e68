"""Output items to text: the formats of ``TYPE``, ``WRITE``, ``PROMPT`` and ``$ENCODE`` (``/Fw.d``, ``/Iw``, ...).

Used by :mod:`~aioadept.vplus.builtins` (TYPE, $ENCODE) and :mod:`~aioadept.vplus.iodev` (WRITE, the device
names of ATTACH and the option strings of FOPEN), which therefore need not import each other.
"""

from __future__ import annotations

import re

from aioadept.vplus import errors as E
from aioadept.vplus.errors import VPlusError

_FMT_RE = re.compile(r"([A-Z])(\d+)?(?:\.(\d+))?\Z")


def _fmt_number(v: float, spec: tuple[str, int | None, int | None]) -> str:
    kind, w, d = spec
    if kind == "F":
        s = "%.*f" % (d if d is not None else 2, v)
    elif kind == "E":
        s = "%.*E" % (d if d is not None else 6, v)
    elif kind == "G":
        s = "%.*G" % (d if d is not None else 6, v)
    elif kind == "I":
        s = "%d" % round(v)
    elif kind == "H":
        s = "%X" % (int(v) & 0xFFFFFFFF)
    elif kind == "O":
        s = "%o" % (int(v) & 0xFFFFFFFF)
    else:  # D: the default format
        s = _default_number(v)
    if w:
        s = s.rjust(w)
    return s


def _default_number(v: float) -> str:
    if v == int(v) and abs(v) < 1e9:
        return "%d" % int(v)
    s = "%.6g" % v
    return s


_FMT_CACHE: dict[str, tuple] = {}     # format text -> (kind, width, decimals): formats are program constants


def _render(items: tuple) -> tuple[str, bool]:
    """Output items (values and ("fmt", spec) constants) to text; True if /S suppressed the line end."""
    for it in items:
        if type(it) is not str:
            break
    else:
        return "".join(items), False        # only strings (WRITE of built lines): nothing to format
    out: list[str] = []
    spec: tuple = ("D", None, None)
    no_eol = False
    for it in items:
        if type(it) is tuple and len(it) == 2 and it[0] == "fmt":
            f = it[1]
            parsed = _FMT_CACHE.get(f)
            if parsed is None:
                m = _FMT_RE.match(f)
                parsed = _FMT_CACHE[f] = (m.group(1) if m else f[:1], int(m.group(2)) if m and m.group(2) else None,
                                          int(m.group(3)) if m and m.group(3) else None)
            kind, num, prec = parsed
            if kind == "S":
                no_eol = True
            elif kind == "X":
                out.append(" " * (num if num is not None else 1))
            elif kind == "C":
                out.append("\r\n" * (num if num is not None else 1))
            elif kind in ("N", "B", "U"):
                pass
            elif kind in ("F", "E", "G", "I", "H", "O", "D"):
                spec = (kind, num, prec)
            else:
                raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* (format /{f})")
            continue
        if isinstance(it, str):
            out.append(it)
        elif isinstance(it, (int, float)):
            out.append(_fmt_number(float(it), spec))
        else:
            out.append(repr(it))
    return "".join(out), no_eol
