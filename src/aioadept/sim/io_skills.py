"""The Python sim's I/O and hand skills: ``signal``, ``sig``, ``wait_sig``, ``open_hand``, ``close_hand``,
``relax_hand`` (docs/protocol.md). Each is a thin wire layer over the controller's :class:`aioadept.sim.io.DigitalIO`,
the model the V+ emulator's instructions drive too; ``vplus/rsskills.V2`` has the same skills for a controller.

Values are checked before anything changes: a signal number that is no signal, or an input given to ``signal``,
is ``ILLEGAL_SIGNAL``; a timeout that is not a finite number > 0 is ``ILLEGAL_VALUE``; a wait that times out is
``SIGNAL_TIMEOUT``. The hand skills are V+'s immediate forms (``OPENI``, ``CLOSEI``, ``RELAXI``): they wait for the
arm to be at rest, switch the valves and ack after ``HAND.TIME``.
"""

from __future__ import annotations

import math
from typing import Any

from aioadept.errors import RobotError
from aioadept.protocol import ErrorCode
from aioadept.sim.io import SignalKind, check_nums, signal_kind
from aioadept.sim.skills import SkillGen, SkillResult, SkillSpec

MAX_WAIT_S = 3600.0
"""Longest ``wait_sig`` timeout accepted (s): a longer one is a client's mistake that would hold the executor."""
WAIT_POLL_S = 0.016
"""How often a waiting ``wait_sig`` looks at its signal again (one V+ trajectory cycle). An input the test API or
the world drives changes between controller events; the hand's own switch wakes it at the exact time."""


def _signal(ctl: Any, args: tuple[float, ...]) -> None:
    nums = check_nums(args)
    ctl.io.signal(nums, ctl.now_s)


def _sig(ctl: Any, args: tuple[float, ...]) -> SkillResult:
    nums = check_nums(args)
    io = ctl.io
    io.advance(ctl.now_s)
    # One field after the pose: each SIG(n), -1 (TRUE) or 0, in the order asked, comma-separated.
    return SkillResult((",".join("-1" if io.state(n) == (n > 0) else "0" for n in nums),))


def _wait_sig(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    n_arg, timeout = args
    (n,) = check_nums((n_arg,))
    if signal_kind(n) is SignalKind.OUTPUT:
        # Only the program itself changes an output, and it is waiting here: such a wait could only time out.
        raise RobotError(ErrorCode.ILLEGAL_SIGNAL, f"wait_sig: signal {abs(n)} is an output (wait for an input "
                                                   f"1001-1512 or a soft signal 2001-2512)")
    if not (math.isfinite(timeout) and 0 < timeout <= MAX_WAIT_S):
        raise RobotError(ErrorCode.ILLEGAL_VALUE, f"wait_sig: timeout {timeout:.6g} s outside (0, {MAX_WAIT_S:g}]")
    io = ctl.io
    end = ctl.now_s + timeout  # server seconds, not scaled: a timeout is the client's wall-clock budget
    while True:
        io.advance(ctl.now_s)
        if io.state(n) == (n > 0):
            return None
        if ctl.now_s >= end:
            raise RobotError(ErrorCode.SIGNAL_TIMEOUT,
                             f"wait_sig: signal {abs(n)} not {'on' if n > 0 else 'off'} after {timeout:g} s")
        wake = min(end, ctl.now_s + WAIT_POLL_S)
        event = io.next_event_s()
        yield wake if event is None or event <= ctl.now_s else min(wake, event)


def _hand(action: str):
    def skill(ctl: Any, args: tuple[float, ...]) -> SkillGen:
        return (yield from ctl.hand_immediate(action))
    skill.__name__ = f"_{action}_hand"
    return skill


def io_skills() -> list[SkillSpec]:
    """The I/O and hand skills of the default table."""
    return [
        SkillSpec("signal", _signal, None),
        SkillSpec("sig", _sig, None),
        SkillSpec("wait_sig", _wait_sig, (2,)),
        SkillSpec("open_hand", _hand("open"), (0,)),
        SkillSpec("close_hand", _hand("close"), (0,)),
        SkillSpec("relax_hand", _hand("relax"), (0,)),
    ]


__all__ = ["MAX_WAIT_S", "io_skills"]
