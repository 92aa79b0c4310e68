"""Binary values in V+ strings: ``$INTB``/``INTB``, ``$LNGB``/``LNGB``, ``$FLTB``/``FLTB``, ``$DBLB``/``DBLB``,
``$TRANSB``/``TRANSB``.

What binary TCP protocols and binary data files in V+ are built from: a number packed into 2, 4 or 8 characters
of a string (each character one byte, 0..255), and read back from a position in a string. The byte order is the
V+ Language Reference Guide's (v17, the ``$LNGB``, ``LNGB``, ``INTB``, ``FLTB`` pages): the first byte holds the
most significant bits ("Bits 25 to 32 are packed into the first byte, followed by bits 17 to 24 in the second
byte"), i.e. network byte order, big-endian. docs/vplus.md ("Binary values in strings") lists the choices where
the pages are silent.

Pure functions registered with the registry's :func:`~aioadept.vplus.registry.builtin` decorator; nothing here
needs a run time.
"""

from __future__ import annotations

import math
import struct

from aioadept.vplus import errors as E
from aioadept.vplus import locations as L
from aioadept.vplus.errors import VPlusError
from aioadept.vplus.registry import builtin


def _round(v: float) -> int:
    """A real where an integer is packed: rounded, halves away from zero (as ``builtins.vint``)."""
    if type(v) is not float and type(v) is not int:
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* (a number is needed)")
    return int(math.floor(v + 0.5)) if v >= 0 else -int(math.floor(0.5 - v))


def _bytes(s: str, first: float | None, n: int, name: str) -> bytes:
    """``n`` characters of ``s`` from position ``first`` (omitted, 0 or 1: the first), as bytes; beyond the end of
    the string is an error (the pages: "An error results if first_char specifies ... beyond the end")."""
    if type(s) is not str:
        raise VPlusError(E.ILLEGAL_OPERATION, f"*Illegal operation* ({name} needs a string)")
    i = 1 if first is None else max(_round(first), 1)
    part = s[i - 1:i - 1 + n]
    if len(part) < n:
        raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* ({name}: {n} bytes from character {i} are beyond the "
                                          f"end of a string of {len(s)})")
    try:
        return part.encode("latin-1")
    except UnicodeEncodeError:
        raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* ({name}: a character is not one byte)") from None


def _chars(b: bytes) -> str:
    return b.decode("latin-1")


@builtin("$INTB")
def _s_intb(v: float) -> str:
    """2 bytes: the low 16 bits of the rounded value, bits 9 to 16 first."""
    return _chars(struct.pack(">H", _round(v) & 0xFFFF))


@builtin("INTB")
def _intb(s: str, first: float | None = None) -> float:
    """Two bytes as a signed 16-bit integer ("The first byte contains bits 9 to 16")."""
    return float(struct.unpack(">h", _bytes(s, first, 2, "INTB"))[0])


@builtin("$LNGB")
def _s_lngb(v: float) -> str:
    """4 bytes: the rounded value, bits 25 to 32 first; outside ^H7FFFFFFF..-^H80000000 is an error (the page:
    "Values must be in the range")."""
    k = _round(v)
    if not -0x80000000 <= k <= 0x7FFFFFFF:
        raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* ($LNGB of {v:g}: outside -^H80000000..^H7FFFFFFF)")
    return _chars(struct.pack(">i", k))


@builtin("LNGB")
def _lngb(s: str, first: float | None = None) -> float:
    """Four bytes as a signed 32-bit integer (a REAL keeps 24 bits of it, a DOUBLE all: the page says so)."""
    return float(struct.unpack(">i", _bytes(s, first, 4, "LNGB"))[0])


@builtin("$FLTB")
def _s_fltb(v: float) -> str:
    """4 bytes: the IEEE single-precision value, sign and exponent first."""
    try:
        return _chars(struct.pack(">f", float(v)))
    except OverflowError:
        raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* ($FLTB of {v:g}: beyond single precision)") from None


@builtin("FLTB")
def _fltb(s: str, first: float | None = None) -> float:
    """Four bytes as an IEEE single: exponent 0 is zero, 255 an overflow error (the FLTB page)."""
    b = _bytes(s, first, 4, "FLTB")
    exp = (b[0] & 0x7F) << 1 | b[1] >> 7
    if exp == 0:
        return 0.0
    if exp == 255:
        raise VPlusError(E.ILLEGAL_VALUE, "*Illegal value* (FLTB: exponent 255, an overflow)")
    return float(struct.unpack(">f", b)[0])


@builtin("$DBLB")
def _s_dblb(v: float) -> str:
    """8 bytes: the IEEE double-precision value, sign and exponent first (byte order UNCONFIRMED: as $FLTB)."""
    return _chars(struct.pack(">d", float(v)))


@builtin("DBLB")
def _dblb(s: str, first: float | None = None) -> float:
    """Eight bytes as an IEEE double: exponent 0 is zero, 2047 an overflow error (as FLTB; UNCONFIRMED)."""
    b = _bytes(s, first, 8, "DBLB")
    exp = (b[0] & 0x7F) << 4 | b[1] >> 4
    if exp == 0:
        return 0.0
    if exp == 2047:
        raise VPlusError(E.ILLEGAL_VALUE, "*Illegal value* (DBLB: exponent 2047, an overflow)")
    return float(struct.unpack(">d", b)[0])


@builtin("$TRANSB")
def _s_transb(t: L.Transform) -> str:
    """48 bytes: the transformation's 12 numbers by column (x, y, z axes, then the position), each as $FLTB."""
    if not isinstance(t, L.Transform):
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* ($TRANSB needs a transformation)")
    return _chars(struct.pack(">12f", *L.columns(t)))


@builtin("TRANSB")
def _transb(s: str, first: float | None = None) -> L.Transform:
    """48 bytes as a transformation (the inverse of $TRANSB); a rotation that is none is *Illegal value*."""
    try:
        return L.Transform(L.by_column(struct.unpack(">12f", _bytes(s, first, 48, "TRANSB"))))
    except ValueError as exc:
        raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* (TRANSB: {exc})") from None
