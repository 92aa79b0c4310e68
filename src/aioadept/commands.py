"""Robot commands, as in the paper's ``pyadept.rcommands``: immutable values that expand to skill calls.

A command is validated when it is built and raises ``ValueError`` naming the field, so nothing invalid reaches the
wire: six finite numbers within :data:`MAX_ABS_MM` (lengths) and :data:`MAX_ABS_DEG` (angles), speed an integer
1..100, a callable skill name, a line of at most 128 characters. The bounds are far beyond any real cell (100 m,
±10000°) and keep every motion line well within V+'s 128 characters under ``%.3f``; ``Skill`` applies them too
when it names one of the motion skills.
Motion commands append ``break`` by default (``break_move=True``), as pyadept does: the robot then finishes the
motion before the next command runs, and the break's ack marks the motion's completion.

    >>> MoveToolZ(2.5).calls()
    (SkillCall(skill='move_rel_tool', args=(0.0, 0.0, 2.5, 0.0, 0.0, 0.0)), SkillCall(skill='break', args=()))
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Sequence

from aioadept.geometry import Pose
from aioadept.protocol import SkillCall

_BREAK = SkillCall("break")

SPEED_MIN, SPEED_MAX = 1, 100
"""The speeds :class:`SetSpeed` accepts, in %: every speed option and cell-file speed quotes these."""
MAX_ABS_MM = 1e5
"""Largest length (mm) a motion command accepts, absolute or relative: 100 m (``-100000.000`` is 11 characters)."""
MAX_ABS_DEG = 1e4
"""Largest angle (deg) a motion command accepts, absolute or relative (``-10000.000`` is 10 characters)."""

_POSE_UNITS = ("mm", "mm", "mm", "deg", "deg", "deg")
_JOINT_UNITS = ("deg",) * 6
_LIMIT = {"mm": MAX_ABS_MM, "deg": MAX_ABS_DEG}


class Command:
    """Base class: a command expands to one or more :class:`SkillCall` (one command message each)."""

    __slots__ = ("_calls",)
    _calls: tuple[SkillCall, ...]

    def calls(self) -> tuple[SkillCall, ...]:
        """The skill calls this command sends, in order."""
        return self._calls

    def __len__(self) -> int:
        return len(self._calls)

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable")

    def _init(self, calls: Iterable[SkillCall]) -> None:
        object.__setattr__(self, "_calls", tuple(calls))

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and other.calls() == self.calls()  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash((type(self).__name__, self._calls))


def _six(name: str, values: Sequence[float] | Pose, units: Sequence[str] = _POSE_UNITS) -> tuple[float, ...]:
    vals = tuple(values)
    if len(vals) != 6:
        raise ValueError(f"{name}: expected 6 numbers, got {len(vals)}")
    return tuple(_bounded(f"{name}[{i}]", v, unit) for i, (v, unit) in enumerate(zip(vals, units)))


def _bounded(name: str, v: object, unit: str) -> float:
    """``v`` as a float: a real number (not bool), finite, within the bound of ``unit`` (mm or deg)."""
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise ValueError(f"{name}: {v!r} is not a number")
    f = float(v)
    if not math.isfinite(f):
        raise ValueError(f"{name}: {v!r} is not finite")
    limit = _LIMIT[unit]
    if abs(f) > limit:
        raise ValueError(f"{name}: {v!r} {unit} is outside ±{limit:g} {unit}")
    return f


class _Motion(Command):
    """A six-number motion skill, followed by ``break`` unless ``break_move=False``."""

    __slots__ = ()
    skill: str = ""
    field_name: str = "pose"
    units: tuple[str, ...] = _POSE_UNITS

    def __init__(self, values: Sequence[float] | Pose, *, break_move: bool = True) -> None:
        call = SkillCall(self.skill, _six(self.field_name, values, self.units))
        self._init((call, _BREAK) if break_move else (call,))

    @property
    def values(self) -> tuple[float, ...]:
        return self._calls[0].args  # type: ignore[return-value]

    @property
    def break_move(self) -> bool:
        return len(self._calls) == 2

    def __repr__(self) -> str:
        vals = ", ".join("%g" % v for v in self.values)
        suffix = "" if self.break_move else ", break_move=False"
        return f"{type(self).__name__}([{vals}]{suffix})"


class MoveTo(_Motion):
    """Move the tool to a pose in the world frame (x, y, z mm; yaw, pitch, roll deg). Skill ``move_to``."""

    __slots__ = ()
    skill = "move_to"


class MoveJoints(_Motion):
    """Joint-interpolated move to joint angles j1..j6 (deg). Skill ``move_joints``."""

    __slots__ = ()
    skill = "move_joints"
    field_name = "joints_deg"
    units = _JOINT_UNITS


class MoveRelWorld(_Motion):
    """Add six numbers component-wise to the current pose (AdeptServer semantics). Skill ``move_rel_world``."""

    __slots__ = ()
    skill = "move_rel_world"
    field_name = "delta"


class MoveRelTool(_Motion):
    """Move relative to the current tool frame (``HERE:TRANS(...)``). Skill ``move_rel_tool``."""

    __slots__ = ()
    skill = "move_rel_tool"
    field_name = "delta"


class MoveRelJoints(_Motion):
    """Displace each joint by the given angles (deg). Skill ``move_rel_joints``."""

    __slots__ = ()
    skill = "move_rel_joints"
    field_name = "delta_joints_deg"
    units = _JOINT_UNITS


class MoveToolZ(MoveRelTool):
    """Move along the tool's z axis by ``delta_z_mm`` (a ``move_rel_tool`` with only z set)."""

    __slots__ = ()

    def __init__(self, delta_z_mm: float, *, break_move: bool = True) -> None:
        dz = _bounded("delta_z_mm", delta_z_mm, "mm")
        super().__init__((0.0, 0.0, dz, 0.0, 0.0, 0.0), break_move=break_move)

    @property
    def delta_z_mm(self) -> float:
        return self.values[2]

    def __repr__(self) -> str:
        suffix = "" if self.break_move else ", break_move=False"
        return f"MoveToolZ({self.delta_z_mm:g}{suffix})"


class SetSpeed(Command):
    """Speed factor 1..100 (%) for the next motion only (V+ ``SPEED`` without ``ALWAYS``). Skill ``set_speed``.

    An integer (the wire carries ``%d``): ``20`` and ``20.0`` are accepted, ``2.5`` is not. 0 is refused although
    the paper's grammar allows it: a motion at 0 % would never end (``aioadept sim`` answers it -410). Use
    ``Skill("set_speed", n)`` to send any integer unchecked, e.g. to test a server.
    """

    __slots__ = ()

    def __init__(self, speed: int) -> None:
        if isinstance(speed, bool) or not isinstance(speed, numbers.Real):
            raise ValueError(f"speed: {speed!r} is not an integer")
        if isinstance(speed, numbers.Integral):
            speed = int(speed)
        elif math.isfinite(speed) and float(speed).is_integer():
            speed = int(speed)
        else:
            raise ValueError(f"speed: {speed!r} is not an integer")
        if not SPEED_MIN <= speed <= SPEED_MAX:
            raise ValueError(f"speed: {speed} is outside {SPEED_MIN}..{SPEED_MAX} (0 % would never end a motion)")
        self._init((SkillCall("set_speed", (speed,)),))

    @property
    def speed(self) -> int:
        return int(self._calls[0].args[0])

    def __repr__(self) -> str:
        return f"SetSpeed({self.speed})"


class _NoArgs(Command):
    __slots__ = ()
    skill: str = ""

    def __init__(self) -> None:
        self._init((SkillCall(self.skill),))

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class Break(_NoArgs):
    """Wait until the robot has completed the current motion and stopped. Skill ``break``."""

    __slots__ = ()
    skill = "break"


class EnableAir(_NoArgs):
    """Open the tool's vacuum valve (digital output). Skill ``enable_air``."""

    __slots__ = ()
    skill = "enable_air"


class DisableAir(_NoArgs):
    """Close the tool's vacuum valve. Skill ``disable_air``."""

    __slots__ = ()
    skill = "disable_air"


class Here(_NoArgs):
    """No motion; the ack carries the current pose (extension). Skill ``here``."""

    __slots__ = ()
    skill = "here"


class Skill(Command):
    """Any user-defined skill: a V+ program name (≤ 15 chars) and numeric arguments.

    ``Skill("open_gripper")``, ``Skill("set_tool", 0, 0, 120, 0, 0, 0)``. Arguments must be finite and the line
    at most 128 characters. A motion skill's name (``move_to``, ``move_rel_tool``, ...) gets its command's bounds
    on each argument given (lengths :data:`MAX_ABS_MM`, angles :data:`MAX_ABS_DEG`); the number of arguments and
    ``set_speed``'s value are left to the server, so ``Skill`` can test how a server answers them.
    """

    __slots__ = ()

    def __init__(self, name: str, *args: int | float) -> None:
        units = _MOTION_UNITS.get(name)
        if units is not None:
            for i, (a, unit) in enumerate(zip(args, units)):
                _bounded(f"args[{i}]", a, unit)
        self._init((SkillCall(name, tuple(args)),))

    def __repr__(self) -> str:
        call = self._calls[0]
        return f"Skill({', '.join([repr(call.skill), *map(repr, call.args)])})"


class Joined(Command):
    """Several commands as one: their skill calls in order."""

    __slots__ = ("commands",)
    commands: tuple[Command, ...]

    def __init__(self, *commands: Command) -> None:
        for i, c in enumerate(commands):
            if not isinstance(c, Command):
                raise ValueError(f"commands[{i}]: {c!r} is not a Command")
        object.__setattr__(self, "commands", commands)
        self._init(call for c in commands for call in c.calls())

    def __repr__(self) -> str:
        return f"Joined({', '.join(map(repr, self.commands))})"


_MOTION_UNITS = {cls.skill: cls.units for cls in (MoveTo, MoveJoints, MoveRelWorld, MoveRelTool, MoveRelJoints)}
