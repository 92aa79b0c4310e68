"""What every robot model shares: joint limits, the jump limit, V+ configuration requests, angle helpers.

Pure numpy, no I/O. The families (:mod:`aioadept.robots.viper`, :mod:`aioadept.robots.scara`) build their
kinematics on these, and the registry (:mod:`aioadept.robots`) hands out their models by name.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from aioadept.errors import RobotError
from aioadept.geometry import NULL, Pose, decompose
from aioadept.protocol import ErrorCode


@dataclass(frozen=True, slots=True)
class JointLimits:
    """Software joint limits, one (min, max) pair per joint: degrees, or mm for a prismatic joint (a SCARA's J3).

    The defaults are the Viper s850's (ViSP ``vpViper850``)."""

    min_deg: tuple[float, ...] = (-170.0, -190.0, -29.0, -190.0, -120.0, -360.0)
    max_deg: tuple[float, ...] = (170.0, 45.0, 256.0, 190.0, 120.0, 360.0)

    def __post_init__(self) -> None:
        if len(self.min_deg) != len(self.max_deg) or any(lo > hi for lo, hi in zip(self.min_deg, self.max_deg, strict=True)):
            raise ValueError(f"JointLimits: expected as many minima as maxima, each <= its maximum, got "
                             f"{self.min_deg} .. {self.max_deg}")

    def violations(self, joints_deg: Sequence[float], *, tol_deg: float = 1e-6) -> list[int]:
        """Indices (0-based) of joints outside their limits."""
        return [i for i, q in enumerate(joints_deg)
                if q < self.min_deg[i] - tol_deg or q > self.max_deg[i] + tol_deg]

    def check(self, joints_deg: Sequence[float]) -> None:
        """Raise ``RobotError(JOINT_LIMIT)`` naming the first joint outside its limits."""
        bad = self.violations(joints_deg)
        if bad:
            i = bad[0]
            raise RobotError(ErrorCode.JOINT_LIMIT,
                             f"J{i + 1} {joints_deg[i]:.3f} outside {self.min_deg[i]:g}..{self.max_deg[i]:g}")


@dataclass(frozen=True, slots=True)
class JumpLimit:
    """How far one inverse-kinematics solution may move any joint, relative to the size of the Cartesian move.

    A target is refused with ``RobotError(JOINT_JUMP)`` when some joint would move more than::

        floor_deg + per_mm_deg * distance_mm + per_rot_deg * rotation_deg

    where ``distance_mm`` is how far the tool point moves (straight line, seed pose to target) and
    ``rotation_deg`` the angle of the rotation between the two tool orientations. With the defaults a 2 mm step
    may move no joint by more than 4 deg, a 1 deg turn of the tool no joint by more than 5 deg, while a deliberate
    move across the workspace is not limited in practice (300 mm allow 302 deg). Away from the singularities the
    Viper's joints move well under 1 deg per mm and about 1 deg per degree of tool rotation, so only the large joint
    motions that a small command should never cause are refused: a wrist flip, J4/J6 unwinding a revolution
    because the nearer equivalent is past a limit, J1 swinging round because the wrist passes near its axis. (A
    SCARA's J3 moves exactly as far as the tool does, in mm: it is never refused by this.)
    """

    floor_deg: float = 2.0
    per_mm_deg: float = 1.0
    per_rot_deg: float = 3.0

    def __post_init__(self) -> None:
        for name in ("floor_deg", "per_mm_deg", "per_rot_deg"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"JumpLimit.{name}: expected a finite number >= 0, got {v!r}")

    def allowed_deg(self, distance_mm: float, rotation_deg: float) -> float:
        """The largest joint motion (deg) allowed for a move of this Cartesian size."""
        return self.floor_deg + self.per_mm_deg * distance_mm + self.per_rot_deg * rotation_deg


DEFAULT_JUMP_LIMIT = JumpLimit()
"""The jump limit ``inverse`` applies unless told otherwise (``jump=None`` turns it off)."""


@dataclass(frozen=True, slots=True)
class Configuration:
    """The arm configuration V+ keeps across motions (LEFTY/RIGHTY, ABOVE/BELOW, FLIP/NOFLIP).

    Each flag is +1 or -1, or 0 when the joints sit on the singularity that separates the two choices
    (then either choice is acceptable for the next motion). A SCARA has only the first (its elbow and wrist are 0).
    """

    shoulder: int  # Viper: +1 wrist centre in front of the J1 axis; SCARA: +1 RIGHTY (J2 > 0)
    elbow: int     # Viper: +1 elbow "above" (like home), -1 the other branch
    wrist: int     # Viper: +1 sin(j5) > 0 (NOFLIP), -1 sin(j5) < 0 (FLIP)


def matches(c: Configuration, want: Configuration) -> bool:
    """True if ``c`` is acceptable where ``want`` is asked for (a 0 on either side accepts both choices)."""
    return all(w == 0 or f == 0 or f == w for f, w in ((c.shoulder, want.shoulder), (c.elbow, want.elbow),
                                                        (c.wrist, want.wrist)))


@dataclass(frozen=True, slots=True)
class ConfigRequest:
    """A configuration the next motion must end in: V+ ``LEFTY``/``RIGHTY`` (``shoulder`` -1/+1), ``BELOW``/
    ``ABOVE`` (``elbow`` -1/+1), ``FLIP``/``NOFLIP`` (``wrist`` -1/+1), ``SINGLE`` (``single``: the last joint
    within -180..180 deg). 0 (or False) leaves that choice to the seed, as without a request.

    Which sign is which V+ word is docs/vplus.md's "Configuration" (UNCONFIRMED for LEFTY/RIGHTY on the Viper)."""

    shoulder: int = 0
    elbow: int = 0
    wrist: int = 0
    single: bool = False

    def changes(self, joints_deg: Sequence[float], model: Any) -> bool:
        """True if ``joints_deg`` is not in the requested configuration of ``model`` (a flag on its singularity
        matches)."""
        c = model.configuration(joints_deg)
        return not matches(c, Configuration(self.shoulder, self.elbow, self.wrist))


def model_joints(name: str, dof: int, values: Sequence[float]) -> tuple[float, ...]:
    """The joint values of an arm with ``dof`` joints from the six the wire (and ``--joints``) carries: a four-axis
    arm's joints first and zeros after them. A non-zero value there would move nothing, so it is refused (``ValueError``
    naming the model) rather than dropped."""
    if len(values) < dof or any(v != 0.0 for v in values[dof:]):
        raise ValueError(f"the {name} has {dof} joints: J{dof + 1}.. must be 0" if len(values) > dof
                         else f"the {name} has {dof} joints, got {len(values)} values")
    return tuple(float(v) for v in values[:dof])


def sign(v: float, eps: float) -> int:
    return 0 if abs(v) < eps else (1 if v > 0 else -1)


def wrap_pi(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def nearest_equivalent(angle_deg: float, ref_deg: float, lo: float, hi: float) -> float | None:
    """The equivalent of ``angle_deg`` (+k*360) inside [lo, hi] nearest to ``ref_deg``, or None if none is."""
    base = angle_deg + 360.0 * round((ref_deg - angle_deg) / 360.0)
    best: float | None = None
    for c in (base, base - 360.0, base + 360.0):
        if lo - 1e-6 <= c <= hi + 1e-6 and (best is None or abs(c - ref_deg) < abs(best - ref_deg)):
            best = c
    return best


def nearest_solution(candidates: Iterable[Sequence[float]], cur: Sequence[float], lo: Sequence[float],
                     hi: Sequence[float], prismatic: Sequence[bool] = ()) -> list[float] | None:
    """Of the candidate joint vectors, the one with the least total motion from ``cur`` once each revolute joint
    takes its +-360 deg equivalent nearest ``cur`` inside [lo, hi] (a prismatic joint must be inside as it is);
    None if none fits. The first of equal costs wins. Joints are independent in both the cost (a sum) and the
    limits (a box), so each joint's nearest equivalent is taken on its own."""
    best: list[float] | None = None
    best_cost = math.inf
    for sol in candidates:
        cand: list[float] = []
        for i, v in enumerate(sol):
            if i < len(prismatic) and prismatic[i]:
                q: float | None = v if lo[i] - 1e-6 <= v <= hi[i] + 1e-6 else None
            else:
                q = nearest_equivalent(v, cur[i], lo[i], hi[i])
            if q is None:
                break
            cand.append(q)
        else:
            cost = sum(abs(a - b) for a, b in zip(cand, cur, strict=True))
            if cost < best_cost:
                best, best_cost = cand, cost
    return best


def move_size(seed: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """How far (mm) and how much (deg) a tool moves from the 4x4 pose ``seed`` to ``target``."""
    distance = float(np.linalg.norm(target[:3, 3] - seed[:3, 3]))
    r = seed[:3, :3].T @ target[:3, :3]
    # Axis-angle sine and cosine: atan2 stays precise for small angles, where acos(trace) loses half the digits.
    sin_rot = 0.5 * math.sqrt((r[2, 1] - r[1, 2]) ** 2 + (r[0, 2] - r[2, 0]) ** 2 + (r[1, 0] - r[0, 1]) ** 2)
    rotation = math.degrees(math.atan2(sin_rot, (float(r[0, 0] + r[1, 1] + r[2, 2]) - 1.0) / 2.0))
    return distance, rotation


def jump_excess(model: Any, sol: Sequence[float], cur: Sequence[float], m_flange: np.ndarray, tool: Pose,
                jump: JumpLimit) -> tuple[int, float, float, float, float] | None:
    """None if ``sol`` moves no joint more than ``jump`` allows for the tool's move from ``cur`` to the flange
    ``m_flange`` (composed with ``tool``); else (worst joint index, its motion, distance mm, rotation deg, allowed)."""
    moves = [abs(a - b) for a, b in zip(sol, cur, strict=True)]
    worst = max(range(len(moves)), key=moves.__getitem__)
    if moves[worst] <= jump.floor_deg:
        return None  # within the floor whatever the Cartesian size: skip the forward kinematics
    seed, target = model.flange_matrix(cur), m_flange
    if tool != NULL:
        t = tool.to_matrix()
        seed, target = seed @ t, target @ t
    distance, rotation = move_size(seed, target)
    allowed = jump.allowed_deg(distance, rotation)
    return None if moves[worst] <= allowed else (worst, moves[worst], distance, rotation, allowed)


def check_joint_path(start_deg: Sequence[float], end_deg: Sequence[float], limits: JointLimits) -> None:
    """Check a joint-interpolated path against the limits; raise ``RobotError(JOINT_LIMIT)`` if it leaves them.

    The limits form a box and a joint-interpolated path is a straight segment in joint space, so the segment lies
    inside the box exactly when both ends do: checking the ends checks every point of the path.
    """
    limits.check(start_deg)
    limits.check(end_deg)


class ArmMethods:
    """What every model computes the same way from its own ``flange_matrix`` and ``limits``."""

    limits: JointLimits

    def flange_matrix(self, joints_deg: Sequence[float]) -> np.ndarray:
        raise NotImplementedError

    def forward(self, joints_deg: Sequence[float], tool: Pose = NULL) -> Pose:
        """Forward kinematics: the tool pose (flange composed with ``tool``, V+ ``TOOL``) for joint values."""
        m = self.flange_matrix(joints_deg)
        if tool != NULL:
            m = m @ tool.to_matrix()
        return decompose(m)

    def check_joint_path(self, start_deg: Sequence[float], end_deg: Sequence[float], *,
                         limits: JointLimits | None = None) -> None:
        """:func:`check_joint_path` against ``limits`` (default: the model's)."""
        check_joint_path(start_deg, end_deg, self.limits if limits is None else limits)


@dataclass(frozen=True, slots=True)
class UrdfJoint:
    """One URDF joint: its name, parent and child link, origin in the parent link (mm), axis, and whether it
    slides (prismatic, mm) or turns (revolute, degrees)."""

    name: str
    parent: str
    child: str
    origin_mm: tuple[float, float, float]
    axis: tuple[float, float, float]
    prismatic: bool = False
    origin_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
