"""The simulated controller's skill table: the AdeptServer skills (``move_to``, ``break``, ``set_speed``, ...) and
our extensions (``stop``, ``here``, ``hello``, ``status``), the value checks they make before anything moves, and
the types of a table entry (:class:`SkillSpec`, :class:`SkillResult`).

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
    return (yield from ctl.move_joints([a + d for a, d in zip(ctl.joints_deg, args)]))


def _break(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    return (yield from ctl.wait_rest())


def _set_speed(ctl: Any, args: tuple[float, ...]) -> None:
    (speed,) = args
    if not ctl.min_speed_pct <= speed <= 100:
        raise RobotError(ErrorCode.ILLEGAL_VALUE, f"speed {speed:.6g} outside {ctl.min_speed_pct:g}..100")
    ctl.pending_speed_pct = float(speed)


def _enable_air(ctl: Any, args: tuple[float, ...]) -> None:
    ctl.signals[AIR_SIGNAL] = True


def _disable_air(ctl: Any, args: tuple[float, ...]) -> None:
    ctl.signals[AIR_SIGNAL] = False


def _here(ctl: Any, args: tuple[float, ...]) -> SkillResult:
    # The ack's pose is HERE already; the joints follow as trailing fields for tools that want them.
    return SkillResult((",".join("%.3f" % j for j in ctl.joints_deg),))


def _hello(ctl: Any, args: tuple[float, ...]) -> SkillResult:
    return SkillResult((str(PROTOCOL_VERSION), f"{SERVER_NAME} {ctl.version}"))


def _status(ctl: Any, args: tuple[float, ...]) -> SkillResult:
    # The sim's arm never loses power and has no E-stop unless a test gives the controller `power`/`estop`
    # attributes; the speed is the program speed of every motion (SPEED ... ALWAYS), as V+ SPEED(2) reports it.
    from aioadept.protocol.messages import sanitize_text
    from aioadept.protocol.robotstatus import RobotStatus, encode_status_fields

    code, text = ctl.last_error
    st = RobotStatus(moving=ctl.trajectory.in_motion(ctl.now_s), speed_pct=ctl.always_speed_pct, error_code=code,
                     power=bool(getattr(ctl, "power", True)), estop=bool(getattr(ctl, "estop", False)))
    pairs, _ = encode_status_fields(st)
    return SkillResult((pairs, sanitize_text(text)) if text else (pairs,))


def _stop_placeholder(ctl: Any, args: tuple[float, ...]) -> None:  # pragma: no cover - never called
    raise AssertionError("stop is handled by the controller")


def _stop_wait(ctl: Any, args: tuple[float, ...]) -> SkillGen:
    return (yield from ctl.wait_rest())


_STOP_RUN = SkillSpec(STOP_SKILL, _stop_wait, (0,))
"""What a stop runs once read: wait for rest. Stops are recognised by this spec (never aborted by a stop)."""


def default_skills() -> list[SkillSpec]:
    """The AdeptServer skills plus our extensions (stop, here, hello)."""
    six = (6,)
    return [
        SkillSpec("move_to", _move_to, six),
        SkillSpec("move_joints", _move_joints, six),
        SkillSpec("move_rel_world", _move_rel_world, six),
        SkillSpec("move_rel_tool", _move_rel_tool, six),
        SkillSpec("move_rel_joints", _move_rel_joints, six),
        SkillSpec("break", _break, (0,)),
        SkillSpec("set_speed", _set_speed, (1,)),
        SkillSpec("enable_air", _enable_air, (0,)),
        SkillSpec("disable_air", _disable_air, (0,)),
        SkillSpec("here", _here, (0,), readonly=True),
        SkillSpec("hello", _hello, (0,), readonly=True),
        SkillSpec("status", _status, (0,), readonly=True),
        SkillSpec("stop", _stop_placeholder, (0,), immediate=True),
    ]
