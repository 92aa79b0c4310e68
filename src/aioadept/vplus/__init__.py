"""A V+ emulator: run Adept V+ programs (``.V2`` modules) on the simulated Viper, in virtual or real time.

- :class:`Emulator` loads modules, calls programs and reads variables (virtual time, for pytest), or serves them
  in real time with TCP (``aioadept sim --vplus``).
- :mod:`~aioadept.vplus.loader`, :mod:`~aioadept.vplus.parse`, :mod:`~aioadept.vplus.compiler`: source to
  Python generator functions; :mod:`~aioadept.vplus.runtime`: tasks, scheduler, clock;
  :mod:`~aioadept.vplus.builtins`: functions and instructions; :mod:`~aioadept.vplus.iodev`: TCP;
  :mod:`~aioadept.vplus.values` and :mod:`~aioadept.vplus.render`: values and output formats, below both (the
  imports form a DAG); :mod:`~aioadept.vplus.keywords`: the V+ keyword index (a typo vs a gap);
  :mod:`~aioadept.vplus.robot` and :mod:`~aioadept.vplus.locations`: the robot and location values.

docs/vplus.md, "The emulator", says what runs, how it is emulated and what is not supported.
"""

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the names as a type checker and the API reference see them; imported lazily below
    from aioadept.vplus.emulator import CallResult, Emulator, GlobalsView, LoadError
    from aioadept.vplus.errors import VPlusError
    from aioadept.vplus.loader import LoadProblem
    from aioadept.vplus.runtime import RealClock, VirtualClock

_WHERE = {"CallResult": "emulator", "Emulator": "emulator", "GlobalsView": "emulator", "LoadError": "emulator",
          "VPlusError": "errors", "LoadProblem": "loader", "RealClock": "runtime", "VirtualClock": "runtime"}


def __getattr__(name: str):
    # Imported on first use: the source tools (aioadept vplus check, the language server) import the front end
    # (aioadept.vplus.check, .parse, .loader) without the run time (asyncio, the robot, numpy)
    if name in _WHERE:
        return getattr(importlib.import_module(f"aioadept.vplus.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'aioadept.vplus' has no attribute {name!r}")


__all__ = ["CallResult", "Emulator", "GlobalsView", "LoadError", "LoadProblem", "RealClock", "VPlusError",
           "VirtualClock"]
