"""Kinematics of the Adept Viper s850 in the V+ joint convention: forward, inverse, joint limits, reach.

Pure numpy, no I/O. The simulated controller (:mod:`aioadept.sim.controller`) plans every motion through here, and
the virtual camera of the vision side places itself relative to poses computed with :func:`forward`.

Model (ViSP ``vpViper850`` / ARTE, FACTS.md), lengths in mm::

    a1 = 75, d1 = 335, a2 = 365, a3 = 90, d4 = 405, d6 = 80 (flange)

In the V+ convention the chain factors as

    R      = Rz(j1) · Ry(j2 + j3) · Rz(j4) · Ry(j5) · Rz(j6)
    wrist  = Rz(j1) · (a1 + a2 cos j2 - a3 cos j23 + d4 sin j23,  0,  d1 - a2 sin j2 + a3 sin j23 + d4 cos j23)
    flange = wrist + d6 · R[:, 2]

which is ViSP's closed-form ``get_fMe`` written compactly. Home ``[0, -90, 180, 0, 90, 0]`` gives
``(480, 0, 710, 0, 180, 0)``: upper arm vertical, forearm horizontal, tool pointing down - the pose in the
real ack quoted in FACTS.md. The wrist is spherical, so the inverse is closed form: position of the wrist centre
gives j1..j3 (two shoulder and two elbow solutions), the remaining rotation gives j4..j6 as Z-Y-Z angles (two wrist
solutions), and J4/J6 may add multiples of 360 deg within their limits.

A robot-related failure raises :class:`aioadept.errors.RobotError` with ``code`` from
:class:`aioadept.protocol.ErrorCode` (``OUT_OF_REACH`` or ``JOINT_LIMIT``), so the controller can turn it into an
``error`` ack without translating.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aioadept.errors import RobotError
from aioadept.geometry import NULL, Pose, decompose, inverse_transform
from aioadept.protocol import ErrorCode

A1_MM = 75.0
D1_MM = 335.0
A2_MM = 365.0
A3_MM = 90.0
D4_MM = 405.0
D6_MM = 80.0

# Forearm as one link from elbow to wrist centre: its length and its angle off the d4 axis.
_L3_MM = math.hypot(A3_MM, D4_MM)
_BETA = math.atan2(A3_MM, D4_MM)

REACH_MM = A1_MM + A2_MM + _L3_MM
"""Largest distance of the wrist centre from the J1 axis (about 854.9 mm, the datasheet reach)."""

HOME_JOINTS_DEG: tuple[float, ...] = (0.0, -90.0, 180.0, 0.0, 90.0, 0.0)
"""The paper's init_move joints: upper arm vertical, forearm horizontal, tool pointing down."""


@dataclass(frozen=True, slots=True)
class JointLimits:
    """Software joint limits in degrees, one (min, max) pair per joint."""

    min_deg: tuple[float, ...] = (-170.0, -190.0, -29.0, -190.0, -120.0, -360.0)
    max_deg: tuple[float, ...] = (170.0, 45.0, 256.0, 190.0, 120.0, 360.0)

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


VIPER_S850_LIMITS = JointLimits()

MAX_JOINT_SPEED_DEG_S: tuple[float, ...] = (250.0, 250.0, 250.0, 375.0, 375.0, 600.0)
"""Maximum joint speeds (ARTE). Acceleration limits are modelled as these divided by a ramp time."""


@dataclass(frozen=True, slots=True)
class Configuration:
    """The arm configuration V+ keeps across motions (LEFTY/RIGHTY, ABOVE/BELOW, FLIP/NOFLIP).

    Each flag is +1 or -1, or 0 when the joints sit on the singularity that separates the two choices
    (then either choice is acceptable for the next motion).
    """

    shoulder: int  # +1: wrist centre in front of the J1 axis (along the arm's x), -1: behind
    elbow: int     # +1: elbow "above" (j3 - beta in (90, 270) deg, like home), -1: the other branch
    wrist: int     # +1: sin(j5) > 0 (NOFLIP), -1: sin(j5) < 0 (FLIP)


def _sign(v: float, eps: float) -> int:
    return 0 if abs(v) < eps else (1 if v > 0 else -1)


def _arm_plane(j2: float, j3: float) -> tuple[float, float]:
    """Wrist centre in the arm plane: (radial distance from the J1 axis, height), radians in, mm out."""
    j23 = j2 + j3
    r = A1_MM + A2_MM * math.cos(j2) - A3_MM * math.cos(j23) + D4_MM * math.sin(j23)
    z = D1_MM - A2_MM * math.sin(j2) + A3_MM * math.sin(j23) + D4_MM * math.cos(j23)
    return r, z


def configuration(joints_deg: Sequence[float]) -> Configuration:
    """The arm configuration of a joint vector."""
    j = [math.radians(v) for v in joints_deg]
    r, _ = _arm_plane(j[1], j[2])
    return Configuration(
        shoulder=_sign(r, 1e-3),
        elbow=_sign(-math.cos(j[2] - _BETA), 1e-6),
        wrist=_sign(math.sin(j[4]), 1e-6),
    )


def _rz(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def flange_matrix(joints_deg: Sequence[float]) -> np.ndarray:
    """4x4 transform of the flange in the robot base frame (mm) for joints in degrees."""
    if len(joints_deg) != 6:
        raise ValueError(f"joints_deg: expected 6 values, got {len(joints_deg)}")
    j1, j2, j3, j4, j5, j6 = (math.radians(v) for v in joints_deg)
    r, z = _arm_plane(j2, j3)
    rot = _rz(j1) @ _ry(j2 + j3) @ _rz(j4) @ _ry(j5) @ _rz(j6)
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = (r * math.cos(j1), r * math.sin(j1), z)
    m[:3, 3] += D6_MM * rot[:, 2]
    return m


def forward(joints_deg: Sequence[float], tool: Pose = NULL) -> Pose:
    """Forward kinematics: the tool pose (flange composed with ``tool``, V+ ``TOOL``) for joints in degrees."""
    m = flange_matrix(joints_deg)
    if tool != NULL:
        m = m @ tool.to_matrix()
    return decompose(m)


def _wrap_pi(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def _solutions_rad(m: np.ndarray, j4_hint: float) -> list[tuple[tuple[float, ...], Configuration]]:
    """All closed-form solutions (radians, each angle in (-pi, pi]) for a flange transform.

    Raises ``RobotError(OUT_OF_REACH)`` when the wrist centre cannot be reached by any configuration.
    """
    rot = m[:3, :3]
    wc = m[:3, 3] - D6_MM * rot[:, 2]
    rho = math.hypot(wc[0], wc[1])
    out: list[tuple[tuple[float, ...], Configuration]] = []
    reach_failed = True
    for shoulder in (1, -1):
        if rho < 1e-9:
            j1 = 0.0 if shoulder == 1 else math.pi  # on the J1 axis: any j1 works; keep it simple
        else:
            j1 = math.atan2(wc[1], wc[0]) if shoulder == 1 else math.atan2(-wc[1], -wc[0])
        u = shoulder * rho - A1_MM
        v = wc[2] - D1_MM
        d = (u * u + v * v - A2_MM ** 2 - _L3_MM ** 2) / (2.0 * A2_MM * _L3_MM)
        if d > 1.0 + 1e-9 or d < -1.0 - 1e-9:
            continue
        reach_failed = False
        d = max(-1.0, min(1.0, d))
        for elbow in (1, -1):
            # |w|^2 = a2^2 + L^2 + 2 a2 L sin(j3 - beta); elbow +1 is the branch of home (j3 - beta > 90 deg).
            s = math.asin(d)
            j3 = (math.pi - s if elbow == 1 else s) + _BETA
            k = complex(A2_MM, 0.0) + _L3_MM * complex(math.cos(math.pi / 2 - j3 + _BETA),
                                                        math.sin(math.pi / 2 - j3 + _BETA))
            j2 = math.atan2(k.imag, k.real) - math.atan2(v, u)
            j2, j3 = _wrap_pi(j2), _wrap_pi(j3)
            rw = _ry(-(j2 + j3)) @ _rz(-j1) @ rot
            sp = math.hypot(rw[2, 0], rw[2, 1])
            for wrist in (1, -1):
                if sp < 1e-9:
                    # j5 ~ 0 (or 180): only j4 + j6 (or j6 - j4) is defined; keep j4 where it is.
                    j5 = math.atan2(sp, rw[2, 2])
                    j4 = j4_hint
                    total = math.atan2(rw[1, 0], rw[0, 0]) if rw[2, 2] > 0 else math.atan2(rw[1, 0], -rw[0, 0])
                    j6 = total - j4 if rw[2, 2] > 0 else j4 - total
                    if wrist == -1:
                        continue
                    wrist = 0  # on the singularity: acceptable from either wrist configuration
                else:
                    j5 = wrist * math.atan2(sp, rw[2, 2])
                    j4 = math.atan2(wrist * rw[1, 2], wrist * rw[0, 2])
                    j6 = math.atan2(wrist * rw[2, 1], -wrist * rw[2, 0])
                sol = (j1, j2, j3, _wrap_pi(j4), j5, _wrap_pi(j6))
                out.append((sol, Configuration(shoulder, elbow, wrist)))
    if reach_failed:
        raise RobotError(ErrorCode.OUT_OF_REACH,
                         f"location out of range (wrist centre {wc[0]:.1f},{wc[1]:.1f},{wc[2]:.1f})")
    return out


def _unwrap_near(angle_deg: float, ref_deg: float, lo: float, hi: float) -> list[float]:
    """Equivalents of ``angle_deg`` (+k*360) inside [lo, hi], nearest to ``ref_deg`` first."""
    base = angle_deg + 360.0 * round((ref_deg - angle_deg) / 360.0)
    cands = [base + 360.0 * k for k in (-1, 0, 1, -2, 2)]
    cands = [c for c in cands if lo - 1e-6 <= c <= hi + 1e-6]
    return sorted(cands, key=lambda c: abs(c - ref_deg))


def inverse(pose: Pose, current_joints_deg: Sequence[float], tool: Pose = NULL, *,
            limits: JointLimits = VIPER_S850_LIMITS) -> tuple[float, ...]:
    """Inverse kinematics: joints (deg) that put the tool at ``pose``.

    Keeps the arm configuration of ``current_joints_deg`` (as V+ does unless told otherwise; a flag on a
    singularity accepts either choice) and, among the equivalent J4/J6 angles (+-360), takes the smallest joint
    motion. Raises ``RobotError`` with ``OUT_OF_REACH`` when no configuration reaches the pose, ``JOINT_LIMIT``
    when the solution in the current configuration lies outside the joint limits.
    """
    if len(current_joints_deg) != 6:
        raise ValueError(f"current_joints_deg: expected 6 values, got {len(current_joints_deg)}")
    m = pose.to_matrix()
    if tool != NULL:
        m = m @ inverse_transform(tool.to_matrix())
    cur = [float(v) for v in current_joints_deg]
    conf = configuration(cur)
    sols = _solutions_rad(m, math.radians(cur[3]))

    def same(flag: int, want: int) -> bool:
        return want == 0 or flag == 0 or flag == want

    best: tuple[float, ...] | None = None
    best_cost = math.inf
    matched_config = False
    for sol, c in sols:
        if not (same(c.shoulder, conf.shoulder) and same(c.elbow, conf.elbow) and same(c.wrist, conf.wrist)):
            continue
        matched_config = True
        deg = [math.degrees(a) for a in sol]
        # J1, J2, J3, J5: the closed form gives them in (-180, 180]; J2 and J3 can exceed that range within the
        # limits (J2 down to -190, J3 up to 256), so try the +-360 equivalents for every joint.
        options = [_unwrap_near(deg[i], cur[i], limits.min_deg[i], limits.max_deg[i]) or [deg[i]]
                   for i in range(6)]
        for cand in itertools.product(*(o[:2] for o in options)):
            if limits.violations(cand):
                continue
            cost = sum(abs(a - b) for a, b in zip(cand, cur))
            if cost < best_cost:
                best, best_cost = tuple(cand), cost
    if best is None:
        if not matched_config:
            raise RobotError(ErrorCode.OUT_OF_REACH, "location out of range in the current configuration")
        # Report the limit the current-configuration solution breaks.
        for sol, c in sols:
            if same(c.shoulder, conf.shoulder) and same(c.elbow, conf.elbow) and same(c.wrist, conf.wrist):
                deg = [math.degrees(a) for a in sol]
                deg = [(_unwrap_near(deg[i], cur[i], -1e9, 1e9) or [deg[i]])[0] for i in range(6)]
                limits.check(deg)
        raise RobotError(ErrorCode.JOINT_LIMIT, "no solution within the joint limits")
    return best


def check_joint_path(start_deg: Sequence[float], end_deg: Sequence[float], *,
                     limits: JointLimits = VIPER_S850_LIMITS) -> None:
    """Check a joint-interpolated path against the limits; raise ``RobotError(JOINT_LIMIT)`` if it leaves them.

    The limits form a box and a joint-interpolated path is a straight segment in joint space, so the segment lies
    inside the box exactly when both ends do: checking the ends checks every point of the path.
    """
    limits.check(start_deg)
    limits.check(end_deg)
