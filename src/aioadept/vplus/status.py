"""V+ functions that report the robot's status, for the emulator: ``STATE(select)`` and ``SWITCH(name)``.

The shipped server's ``status`` skill and its state stream (``vplus/rsstate.V2``) read the robot through them.
They come from the V+ Reference Guide (docs/vplus.md, "Status"):

- ``STATE(1)``: the overall robot state; 7 = "robot is under program control" (high power on), 2 = "waiting for
  user to turn on robot power".
- ``STATE(2)``: the state of the current or previous motion; 0 = no motion instruction executed yet, 1 = normal
  trajectory evaluation in progress, 2 = stopped at a planned location, 5/6 = "decelerating/stopped due to a
  triggered REACTI or BRAKE instruction" (here a BRAKE: REACTI is not emulated), 7/8 = decelerating/stopped after a
  hardware error, panic button or E-stop.
- ``STATE(3)``: the manual control mode; 5 = "computer control enabled" (the sixth of the manual's list, counted
  from 0 as selects 1 and 2 are: UNCONFIRMED), the only mode a program-controlled emulated arm is in.
- ``STATE(4)``: the front panel's and hardware's status bits; their meanings were not in our copy of the page, so
  no bit is set (UNCONFIRMED).
- ``SWITCH(POWER)``: TRUE while high power is on (UNCONFIRMED as a readable switch; V+ has ``ENABLE POWER``).

Other selects (5 to 9 ...) are refused with *Illegal value* naming the gap: the page's tables for them were not in
our copy, and a made-up value (0 for "in motion"?) could tell a program the arm is at rest while it moves.

The emulated robot never loses power and has no E-stop: ``power`` and ``estop`` of the sim's controller, when it
has such attributes (a test may set them), are read; otherwise power is on and no E-stop is pressed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from aioadept.vplus import errors as E
from aioadept.vplus.errors import VPlusError

TRUE = -1.0
FALSE = 0.0


def functions(rt: Any) -> dict[str, Callable[..., float]]:
    """The V+ functions of this module, bound to the runtime ``rt`` (merged into the builtins' table)."""

    def controller() -> Any:
        r = rt.robot
        if r is None:
            raise VPlusError(E.ROBOT_NOT_ATTACHED, "*Robot not attached* (the emulator has no robot)")
        r.now_s = rt.now
        return r.controller

    def power_on() -> bool:
        return bool(getattr(controller(), "power", True))

    def state(select: float = 1.0) -> float:
        sel = int(select)
        ctl = controller()
        if sel == 1:
            return 7.0 if power_on() else 2.0
        if sel == 2:
            traj = ctl.trajectory
            estop = bool(getattr(ctl, "estop", False))
            braked = bool(getattr(rt.robot, "braked", False))
            if traj.in_motion(ctl.now_s):
                return 7.0 if estop else (5.0 if braked else 1.0)
            if estop:
                return 8.0
            if braked:
                return 6.0
            return 2.0 if traj.t_rest_s > 0 else 0.0
        if sel == 3:
            return 5.0   # computer control enabled (the numbering UNCONFIRMED: module docstring)
        if sel == 4:
            return 0.0   # the status bits: none known (UNCONFIRMED)
        raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* (STATE({sel}) is not implemented by the emulator: the "
                                          "manual's table for it was not in our copy)")

    def switch(name: str = "") -> float:
        n = str(name).upper()
        if n == "POWER":
            return TRUE if power_on() else FALSE
        if n in rt.switches:
            return TRUE if rt.switches[n] else FALSE
        raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* (no switch {n})")

    return {"STATE": state, "SWITCH": switch}
