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
    return tuple(_bounded(f"{name}[{i}]", v, unit) for i, (v, unit) in enumerate(zip(vals, units, strict=True)))


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


# -- digital I/O and the hand (docs/protocol.md; the servers' model: aioadept.sim.io) -----------------------------

SIGNAL_RANGES = {"output": range(1, 513), "input": range(1001, 1513), "soft": range(2001, 2513)}
"""V+ signal numbers: digital outputs, digital inputs, internal soft signals (a server answers any other number,
or one of the wrong kind, with ILLEGAL_SIGNAL)."""
MAX_SIGNALS = 16
"""Most signal numbers in one ``signal``/``sig`` (the V+ server's argument limit)."""
MAX_WAIT_S = 3600.0
"""Longest ``wait_sig`` timeout a server accepts (s)."""


def _signal_kind(n: int) -> str | None:
    return next((kind for kind, rng in SIGNAL_RANGES.items() if abs(n) in rng), None)


def _signals(name: str, nums: Sequence[int], kinds: tuple[str, ...]) -> tuple[int, ...]:
    if not 1 <= len(nums) <= MAX_SIGNALS:
        raise ValueError(f"{name}: 1 to {MAX_SIGNALS} signal numbers, got {len(nums)}")
    out = []
    for i, n in enumerate(nums):
        if isinstance(n, bool) or not isinstance(n, numbers.Real) or not math.isfinite(n) or n != int(n):
            raise ValueError(f"{name}[{i}]: {n!r} is not an integer signal number")
        n = int(n)
        kind = _signal_kind(n)
        if kind is None:
            raise ValueError(f"{name}[{i}]: no signal {abs(n)} (outputs 1-512, inputs 1001-1512, soft 2001-2512)")
        if kind not in kinds:
            raise ValueError(f"{name}[{i}]: signal {abs(n)} is an {kind}; {name} takes {' or '.join(kinds)} signals")
        out.append(n)
    return tuple(out)


class Signal(Command):
    """Switch outputs (1-512) and soft signals (2001-2512): n on, -n off, as V+ ``SIGNAL``. Skill ``signal``.

    ``Signal(8, -3)`` turns output 8 on and 3 off. An input (1001-1512) or a number that is no signal raises
    ``ValueError`` here, before anything is sent."""

    __slots__ = ()

    def __init__(self, *signals: int) -> None:
        self._init((SkillCall("signal", _signals("signals", signals, ("output", "soft"))),))

    @property
    def signals(self) -> tuple[int, ...]:
        return self._calls[0].args  # type: ignore[return-value]

    def __repr__(self) -> str:
        return f"Signal({', '.join(map(str, self.signals))})"


class Sig(Command):
    """Read signals, as V+ ``SIG()`` of each: the ack carries one state per number after the pose (-1 if the
    signal is on, or off for -n; else 0). :meth:`states` reads them from the ack. Skill ``sig``."""

    __slots__ = ()

    def __init__(self, *signals: int) -> None:
        self._init((SkillCall("sig", _signals("signals", signals, tuple(SIGNAL_RANGES))),))

    @property
    def signals(self) -> tuple[int, ...]:
        return self._calls[0].args  # type: ignore[return-value]

    @staticmethod
    def states(ack: object) -> tuple[bool, ...]:
        """The states a ``sig`` ack carries (True where SIG(n) is TRUE); ValueError if it carries none."""
        extra = getattr(ack, "extra", ())
        if not extra or not extra[0]:
            raise ValueError("the ack carries no signal states")
        return tuple(v.strip() == "-1" for v in extra[0].split(","))

    def __repr__(self) -> str:
        return f"Sig({', '.join(map(str, self.signals))})"


class WaitSig(Command):
    """Wait until an input (1001-1512) or soft signal (2001-2512) is on (off for a negative number), at most
    ``timeout_s`` seconds; the server answers an error ack (SIGNAL_TIMEOUT) on timeout. Skill ``wait_sig``."""

    __slots__ = ()

    def __init__(self, signal: int, timeout_s: float) -> None:
        (n,) = _signals("signal", (signal,), ("input", "soft"))
        if isinstance(timeout_s, bool) or not isinstance(timeout_s, numbers.Real):
            raise ValueError(f"timeout_s: {timeout_s!r} is not a number")
        t = float(timeout_s)
        if not (math.isfinite(t) and 0 < t <= MAX_WAIT_S):
            raise ValueError(f"timeout_s: {timeout_s!r} is outside (0, {MAX_WAIT_S:g}] s")
        self._init((SkillCall("wait_sig", (n, t)),))

    @property
    def signal(self) -> int:
        return int(self._calls[0].args[0])

    @property
    def timeout_s(self) -> float:
        return float(self._calls[0].args[1])

    def __repr__(self) -> str:
        return f"WaitSig({self.signal}, {self.timeout_s:g})"


class OpenHand(_NoArgs):
    """Open the hand now (V+ ``OPENI``): the server waits for the arm to be at rest, switches the hand and acks
    after ``HAND.TIME``. Skill ``open_hand``."""

    __slots__ = ()
    skill = "open_hand"


class CloseHand(_NoArgs):
    """Close the hand now (V+ ``CLOSEI``; see :class:`OpenHand`). Whether it closed on a part shows on the
    gripper's closed-fully switch (an input): ``WaitSig(-1001, t)`` or ``Sig(1001)``. Skill ``close_hand``."""

    __slots__ = ()
    skill = "close_hand"


class RelaxHand(_NoArgs):
    """Relax the hand now: both valves off (V+ ``RELAXI``; see :class:`OpenHand`). Skill ``relax_hand``."""

    __slots__ = ()
    skill = "relax_hand"


class GetStatus(_NoArgs):
    """No motion; the ack carries the robot's status (extension, docs/protocol.md 4.7): read it with
    :func:`aioadept.protocol.robotstatus.parse_status_fields` or call ``RobotClient.status()``. Skill ``status``."""

    __slots__ = ()
    skill = "status"


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
            # the values given are bounded; a wrong count is the server's to refuse, with its error code
            for i, (a, unit) in enumerate(zip(args, units, strict=False)):
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


# -- straight-line and approach motions (V+ MOVES, APPRO, APPROS, DEPART, DEPARTS) ----------------------

class MoveToS(_Motion):
    """Move the tool to a pose on a straight line (V+ ``MOVES``): the straight-line form of :class:`MoveTo`.
    Skill ``move_to_s``; a line through a singularity or past a joint limit is refused before the arm moves."""

    __slots__ = ()
    skill = "move_to_s"


class MoveRelToolS(_Motion):
    """Move relative to the current tool frame on a straight line: the straight-line form of
    :class:`MoveRelTool`. Skill ``move_rel_tool_s``."""

    __slots__ = ()
    skill = "move_rel_tool_s"
    field_name = "delta"


class Appro(Command):
    """Move to ``distance_mm`` from ``pose`` back along its tool Z axis (V+ ``APPRO pose, distance``: the location
    ``pose:TRANS(0, 0, -distance)``; positive is away from the part for a tool whose Z points into it),
    joint-interpolated. Skill ``appro:x,y,z,yaw,pitch,roll,dist``; ``break`` follows unless ``break_move=False``."""

    __slots__ = ()
    skill: str = "appro"

    def __init__(self, pose: Sequence[float] | Pose, distance_mm: float, *, break_move: bool = True) -> None:
        args = (*_six("pose", pose), _bounded("distance_mm", distance_mm, "mm"))
        call = SkillCall(self.skill, args)
        self._init((call, _BREAK) if break_move else (call,))

    @property
    def pose(self) -> Pose:
        return Pose(*self._calls[0].args[:6])

    @property
    def distance_mm(self) -> float:
        return float(self._calls[0].args[6])

    def __repr__(self) -> str:
        vals = ", ".join("%g" % v for v in self.pose)
        suffix = "" if len(self._calls) == 2 else ", break_move=False"
        return f"{type(self).__name__}([{vals}], {self.distance_mm:g}{suffix})"


class Appros(Appro):
    """:class:`Appro` on a straight line (V+ ``APPROS``). Skill ``appros``."""

    __slots__ = ()
    skill = "appros"


class Depart(Command):
    """The tool moves ``distance_mm`` back along its own Z axis (V+ ``DEPART distance``: positive backs away from
    the part), joint-interpolated, from where the planned motions end (with a break before it: where the arm
    is). Skill ``depart:dist``; ``break`` follows unless ``break_move=False``."""

    __slots__ = ()
    skill: str = "depart"

    def __init__(self, distance_mm: float, *, break_move: bool = True) -> None:
        call = SkillCall(self.skill, (_bounded("distance_mm", distance_mm, "mm"),))
        self._init((call, _BREAK) if break_move else (call,))

    @property
    def distance_mm(self) -> float:
        return float(self._calls[0].args[0])

    def __repr__(self) -> str:
        suffix = "" if len(self._calls) == 2 else ", break_move=False"
        return f"{type(self).__name__}({self.distance_mm:g}{suffix})"


class Departs(Depart):
    """:class:`Depart` on a straight line (V+ ``DEPARTS``). Skill ``departs``."""

    __slots__ = ()
    skill = "departs"


_MOTION_UNITS.update({MoveToS.skill: MoveToS.units, MoveRelToolS.skill: MoveRelToolS.units,
                      Appro.skill: (*_POSE_UNITS, "mm"), Appros.skill: (*_POSE_UNITS, "mm"),
                      Depart.skill: ("mm",), Departs.skill: ("mm",)})
