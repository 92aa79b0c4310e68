"""The values V+ programs hold, as the emulator's run time represents them: REAL rounding, the string limit, the
containers of omitted arguments and of location arrays, and the GOTO signal of generated code.

The bottom of the emulator's import graph (errors aside): :mod:`~aioadept.vplus.builtins` (the functions and
instructions) and :mod:`~aioadept.vplus.runtime` (tasks and scheduler) both use these, and runtime imports builtins,
so they live here rather than in either.
"""

from __future__ import annotations

from array import array
from typing import Any

from aioadept.vplus import errors as E
from aioadept.vplus.errors import VPlusError

MAX_STRING = 128
"""Characters a V+ string holds (V+ Language User's Guide, "String Data Type")."""

_FB = array("f", [0.0])


def f32(x: float) -> float:
    """A value as a V+ REAL stores it (IEEE single precision)."""
    _FB[0] = x
    return _FB[0]


class _Goto(BaseException):
    def __init__(self, pc: int) -> None:
        self.pc = pc


_GOTO = [_Goto(i) for i in range(4096)]


class _Missing(dict):
    """The container of an omitted argument: reading it is an undefined value."""


class _LocArray(dict):
    """An array of transformations: storing anything else in it is an error (V+ Language User's Guide v17,
    p. 105: "If a data type different from the one the array was originally created with is specified, an error
    will result"). Arrays of reals stay plain dicts (their stores are the hot path); a location stored into a
    plain dict that holds reals is refused by ``_loc_store``."""

    __slots__ = ("name",)

    def __setitem__(self, k: Any, v: Any) -> None:
        if type(v) is float or type(v) is int or isinstance(v, str):
            raise VPlusError(E.ILLEGAL_OPERATION, f"*Illegal operation* (array {getattr(self, 'name', '')}[] holds "
                                                  "locations: a number cannot be stored in it)")
        dict.__setitem__(self, k, v)
