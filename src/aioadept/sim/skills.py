"""The simulated controller's skill table: the AdeptServer skills (``move_to``, ``break``, ``set_speed``, ...) and
our extensions (``stop``, ``here``, ``hello``, ``status``; the digital I/O and hand skills, in their own block),
the value checks they make before anything moves, and the types of a table entry (:class:`SkillSpec`,
:class:`SkillResult`).

A skill is ``skill(ctl, args)`` with ``ctl`` the :class:`aioadept.sim.controller.Controller` (not imported here:
the controller reads this table, never the other way round). :func:`default_skills` is the table a new controller
starts with; :meth:`aioadept.sim.controller.Controller.register` adds user skills.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from typing import Any, Union

from aioadept.errors import RobotError
from aioadept.geometry import Pose, rel_tool, rel_world
from aioadept.protocol import PROTOCOL_VERSION, STOP_SKILL, ErrorCode
from aioadept.sim.io import SignalKind, check_nums, signal_kind

SERVER_NAME = "aioadept-sim"
MIN_SPEED_PCT = 1.0
"""Lowest program speed accepted by set_speed. The V+ manuals give SPEED's scale (100 = normal full speed, 50 =
half) but no lower bound; the protocol's set_speed argument is an integer 0..100 in the paper's grammar, so 1 % is
the slowest speed a client of the original protocol can ask for. Below it a motion would hold the single executor
(and every client's queue) for hours."""
MAX_POSITION_MM = 10_000.0
"""Largest position or displacement component accepted (mm): ten times the Viper s850's reach."""
MAX_ROTATION_DEG = 360.0
"""Largest pose rotation (yaw, pitch, roll, absolute or relative) accepted, in degrees: a full turn. Beyond it the
value is a client's error (1e20 deg), never a motion."""
MAX_JOINT_DEG = 3600.0
"""Largest joint angle or joint displacement accepted before the joint-limit check (ten turns)."""
AIR_SIGNAL = 8
"""The digital output that enable_air / disable_air switch (AdeptServer uses signal 8)."""

@dataclass(frozen=True, slots=True)
class SkillResult:
    """What a finished skill answers: trailing fields after the pose (``extra``)."""

    extra: tuple[str, ...] = ()


SkillGen = Generator[float, None, Union[SkillResult, None]]
SkillFunc = Callable[[Any, tuple[float, ...]], Union[SkillResult, None, SkillGen]]


@dataclass(frozen=True, slots=True)
class SkillSpec:
    """One entry of the skill table.

    ``nargs``: the argument counts accepted (None: any). ``immediate``: served when read instead of queued (only
    for skills that never move the arm or wait; ``stop`` is handled by the controller itself). ``readonly``: a
    query that neither moves nor waits nor changes state; served when read if its connection has nothing pending
    (so it never waits behind another client's motion), else in turn behind that connection's own commands.
    """

    name: str
    func: SkillFunc
    nargs: tuple[int, ...] | None = (0,)
    immediate: bool = False
    readonly: bool = False


# -- the AdeptServer skills ------------------------------------------------------------------------------------

def _finite(args: Sequence[float]) -> None:
    for a in args:
        if not math.isfinite(a):
            raise RobotError(ErrorCode.ILLEGAL_VALUE, "argument is not finite")


def _check_pose_args(args: Sequence[float], what: str) -> None:
    """Six pose numbers: finite, positions within MAX_POSITION_MM, rotations within MAX_ROTATION_DEG.

    Checked before any arithmetic: trigonometry of 1e20 degrees is noise that can land on a reachable pose.
    """
    _finite(args)
    for i, a in enumerate(args):
        if i < 3 and abs(a) > MAX_POSITION_MM:
            raise RobotError(ErrorCode.ILLEGAL_VALUE, f"{what} {'xyz'[i]} {a:.6g} mm beyond +-{MAX_POSITION_MM:g}")
        if i >= 3 and abs(a) > MAX_ROTATION_DEG:
            raise RobotError(ErrorCode.ILLEGAL_VALUE,
                             f"{what} rotation {a:.6g} deg beyond +-{MAX_ROTATION_DEG:g}")


def _check_joint_args(args: Sequence[float], what: str) -> None:
    # Angles a joint could have (within a few turns) go on to the joint-limit check, which names the joint
    # (JOINT_LIMIT); only absurd magnitudes stop here.
    _finite(args)
    for i, a in enumerate(args):
        if abs(a) > MAX_JOINT_DEG:
            raise RobotError(ErrorCode.ILLEGAL_VALUE, f"{what} J{i + 1} {a:.6g} deg beyond +-{MAX_JOINT_DEG:g}")


def _move_to(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    _check_pose_args(args, "target")
    return (yield from ctl.move_pose(Pose(*args)))


def _move_joints(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    _check_joint_args(args, "target")
    return (yield from ctl.move_joints(args))


def _move_rel_world(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    _check_pose_args(args, "displacement")
    return (yield from ctl.move_pose(rel_world(ctl.here, args)))


def _move_rel_tool(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    _check_pose_args(args, "displacement")
    return (yield from ctl.move_pose(rel_tool(ctl.here, args)))


def _move_rel_joints(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    _check_joint_args(args, "displacement")
    here = ctl.joints_deg
    # a four-axis arm's displacement keeps its trailing values, so that a non-zero one is refused, not dropped
    return (yield from ctl.move_joints([a + d for a, d in zip(here, args, strict=False)] + list(args[len(here):])))


def _break(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    return (yield from ctl.wait_rest())


def _set_speed(ctl: Any, args: tuple[float, ...]) -> None:
    (speed,) = args
    if not ctl.min_speed_pct <= speed <= 100:
        raise RobotError(ErrorCode.ILLEGAL_VALUE, f"speed {speed:.6g} outside {ctl.min_speed_pct:g}..100")
    ctl.pending_speed_pct = float(speed)


def _enable_air(ctl: Any, args: tuple[float, ...]) -> None:
    ctl.io.signal((AIR_SIGNAL,), ctl.now_s)


def _disable_air(ctl: Any, args: tuple[float, ...]) -> None:
    ctl.io.signal((-AIR_SIGNAL,), ctl.now_s)


def _here(ctl: Any, args: tuple[float, ...]) -> SkillResult:
    # The ack's pose is HERE already; the joints follow as trailing fields for tools that want them.
    return SkillResult((",".join("%.3f" % j for j in ctl.joints_deg),))


def _hello(ctl: Any, args: tuple[float, ...]) -> SkillResult:
    return SkillResult((str(PROTOCOL_VERSION), f"{SERVER_NAME} {ctl.version}"))


# -- straight-line and approach skills (V+ MOVES, APPRO, APPROS, DEPART, DEPARTS) ---------------------

def _check_distance(d: float, what: str) -> None:
    _finite((d,))
    if abs(d) > MAX_POSITION_MM:
        raise RobotError(ErrorCode.ILLEGAL_VALUE, f"{what} {d:.6g} mm beyond +-{MAX_POSITION_MM:g}")


def approach_pose(loc: Pose, dist_mm: float) -> Pose:
    """V+ ``APPRO loc, dist`` target: ``dist`` mm from ``loc`` back along its tool Z axis, ``loc:TRANS(0,0,-dist)``
    (positive ``dist``: away from the part, for a tool whose Z points into it)."""
    return rel_tool(loc, (0.0, 0.0, -dist_mm, 0.0, 0.0, 0.0))


def _move_to_s(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    _check_pose_args(args, "target")
    return (yield from ctl.move_line(Pose(*args)))


def _move_rel_tool_s(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    # HERE when the skill runs, as move_rel_tool (the paper's skill reads HERE too).
    _check_pose_args(args, "displacement")
    return (yield from ctl.move_line(rel_tool(ctl.here, args)))


def _appro_target(args: tuple[float, ...]) -> Pose:
    _check_pose_args(args[:6], "location")
    _check_distance(args[6], "distance")
    return approach_pose(Pose(*args[:6]), args[6])


def _appro(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    return (yield from ctl.move_pose(_appro_target(args)))


def _appros(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    return (yield from ctl.move_line(_appro_target(args)))


def _depart_target(ctl: Any, args: tuple[float, ...]) -> Pose:
    # From where the planned motions end, as V+ DEPART (and the emulator's) does: with a break before it, HERE.
    _check_distance(args[0], "distance")
    return approach_pose(ctl.planned_end_pose(), args[0])


def _depart(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    return (yield from ctl.move_pose(_depart_target(ctl, args)))


def _departs(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    return (yield from ctl.move_line(_depart_target(ctl, args)))


def line_skills() -> list[SkillSpec]:
    """The straight-line forms of the paper's skills and V+'s approach/depart motions (docs/protocol.md)."""
    return [
        SkillSpec("move_to_s", _move_to_s, (6,)),
        SkillSpec("move_rel_tool_s", _move_rel_tool_s, (6,)),
        SkillSpec("appro", _appro, (7,)),
        SkillSpec("appros", _appros, (7,)),
        SkillSpec("depart", _depart, (1,)),
        SkillSpec("departs", _departs, (1,)),
    ]


def _status(ctl: Any, args: tuple[float, ...]) -> SkillResult:
    # The sim's arm never loses power and has no E-stop unless a test gives the controller `power`/`estop`
    # attributes; the speed is the program speed of every motion (SPEED ... ALWAYS), as V+ SPEED(2) reports it.
    from aioadept.protocol.messages import sanitize_text
    from aioadept.protocol.robotstatus import RobotStatus, encode_status_fields, hand_of_valves

    code, text = ctl.last_error
    io = ctl.io
    wired = io.hand_config  # the valves switch at once (the fingers follow): no time to advance
    st = RobotStatus(moving=ctl.trajectory.in_motion(ctl.now_s), speed_pct=ctl.always_speed_pct, error_code=code,
                     power=bool(getattr(ctl, "power", True)), estop=bool(getattr(ctl, "estop", False)),
                     hand=hand_of_valves(io.state(wired.open_signal), io.state(wired.close_signal)),
                     time_scale=ctl.trajectory.time_scale)
    pairs, _ = encode_status_fields(st)
    return SkillResult((pairs, sanitize_text(text)) if text else (pairs,))


def _stop_placeholder(ctl: Any, args: tuple[float, ...]) -> None:  # pragma: no cover - never called
    raise AssertionError("stop is handled by the controller")


def _stop_wait(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    return (yield from ctl.wait_rest())


_STOP_RUN = SkillSpec(STOP_SKILL, _stop_wait, (0,))
"""What a stop runs once read: wait for rest. Stops are recognised by this spec (never aborted by a stop)."""


def default_skills() -> list[SkillSpec]:
    """The AdeptServer skills plus our extensions (stop, here, hello; the straight-line skills; the I/O and hand
    skills of the block below)."""
    six = (6,)
    return [
        SkillSpec("move_to", _move_to, six),
        SkillSpec("move_joints", _move_joints, six),
        SkillSpec("move_rel_world", _move_rel_world, six),
        SkillSpec("move_rel_tool", _move_rel_tool, six),
        SkillSpec("move_rel_joints", _move_rel_joints, six),
        *line_skills(),
        SkillSpec("break", _break, (0,)),
        SkillSpec("set_speed", _set_speed, (1,)),
        SkillSpec("enable_air", _enable_air, (0,)),
        SkillSpec("disable_air", _disable_air, (0,)),
        SkillSpec("here", _here, (0,), readonly=True),
        SkillSpec("hello", _hello, (0,), readonly=True),
        SkillSpec("status", _status, (0,), readonly=True),
        SkillSpec("stop", _stop_placeholder, (0,), immediate=True),
        *io_skills(),
    ]


# -- digital I/O and the hand ----------------------------------------------------------------------------------
# signal, sig, wait_sig, open_hand, close_hand, relax_hand (docs/protocol.md): a thin wire layer over the
# controller's aioadept.sim.io.DigitalIO, the model the V+ emulator's instructions drive too (vplus/rsskills.V2 has
# the same skills for a controller). Values are checked before anything changes: a number that is no signal, or an
# input given to signal, is ILLEGAL_SIGNAL; a timeout that is not a finite number in (0, MAX_WAIT_S] is
# ILLEGAL_VALUE; a wait that times out is SIGNAL_TIMEOUT. The hand skills are V+'s immediate forms (OPENI, CLOSEI,
# RELAXI): they wait for the arm to be at rest, switch the valves and ack after HAND.TIME.
MAX_WAIT_S = 3600.0
"""Longest ``wait_sig`` timeout accepted (s): a longer one is a client's mistake that would hold the executor."""
WAIT_POLL_S = 0.016
"""How often a waiting ``wait_sig`` looks at its signal again (one V+ trajectory cycle). An input the test API or
the world drives changes between controller events; the hand's own switch wakes it at the exact time."""


def _signal(ctl: Any, args: tuple[float, ...]) -> None:
    nums = check_nums(args)
    ctl.io.signal(nums, ctl.now_s)


def _sig(ctl: Any, args: tuple[float, ...]) -> SkillResult:
    nums = check_nums(args, skill="sig")
    io = ctl.io
    io.advance(ctl.now_s)
    # One field after the pose: each SIG(n), -1 (TRUE) or 0, in the order asked, comma-separated.
    return SkillResult((",".join("-1" if io.state(n) == (n > 0) else "0" for n in nums),))


def _wait_sig(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    n_arg, timeout = args
    (n,) = check_nums((n_arg,))
    if signal_kind(n) is SignalKind.OUTPUT:
        # Only the program itself changes an output, and it is waiting here: such a wait could only time out.
        raise RobotError(ErrorCode.ILLEGAL_SIGNAL, f"signal {abs(n)} is an output (wait for an input "
                                                   f"1001-1512 or a soft signal 2001-2512)")
    if not (math.isfinite(timeout) and 0 < timeout <= MAX_WAIT_S):
        raise RobotError(ErrorCode.ILLEGAL_VALUE, f"timeout {timeout:.6g} s outside (0, {MAX_WAIT_S:g}]")
    io = ctl.io
    end = ctl.now_s + timeout  # server seconds, not scaled: a timeout is the client's wall-clock budget
    while True:
        io.advance(ctl.now_s)
        if io.state(n) == (n > 0):
            return None
        if ctl.now_s >= end:
            raise RobotError(ErrorCode.SIGNAL_TIMEOUT,
                             f"signal {abs(n)} not {'on' if n > 0 else 'off'} after {timeout:g} s")
        wake = min(end, ctl.now_s + WAIT_POLL_S)
        event = io.next_event_s()
        yield wake if event is None or event <= ctl.now_s else min(wake, event)


def _hand(action: str):
    def skill(ctl: Any, args: tuple[float, ...]) -> SkillGen:
        # V+ OPENI/CLOSEI/RELAXI: wait for the arm to be at rest (the gripper never acts on a moving arm),
        # switch the valves, hold for HAND.TIME.
        yield from ctl.wait_rest()
        ctl.io.hand_now(action, ctl.now_s)
        end = ctl.now_s + ctl.io.hand_hold_s()
        while ctl.now_s < end:
            yield end
        return None
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

