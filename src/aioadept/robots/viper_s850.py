"""Kinematics of the Adept Viper s850 in the V+ joint convention: forward, inverse, joint limits, reach.

Pure numpy, no I/O. The simulated controller (:mod:`aioadept.sim.controller`) plans every motion through here, and
the virtual camera of the vision side places itself relative to poses computed with :func:`forward`; it lives in
``robots/`` so that neither has to import the other (``aioadept.sim.kinematics`` is kept as a compatibility alias).

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

:func:`inverse` continues from the current joints: it keeps the arm configuration, takes the nearest solution, and
refuses (``JOINT_JUMP``) a target whose joint motion is out of proportion to its Cartesian size
(:class:`JumpLimit`), so that a small command can never flip the wrist or swing a joint round a singularity.

A robot-related failure raises :class:`aioadept.errors.RobotError` with ``code`` from
:class:`aioadept.protocol.ErrorCode` (``OUT_OF_REACH``, ``JOINT_LIMIT`` or ``JOINT_JUMP``), so the controller can
turn it into an ``error`` ack, before any motion, without translating.
"""

from __future__ import annotations

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

WRIST_SINGULAR_SIN = 1e-4
"""Below this sin(J5) the wrist counts as singular: J4 keeps the seed value and J5, J6 are fitted to the target.
The fit leaves an orientation error of at most this many radians (0.006 deg: 0.008 mm at the flange, 0.03 mm at
the tip of a 300 mm tool, within the Viper's repeatability); everywhere else the solution is exact."""


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


def _solutions_rad(m: np.ndarray, j4_hint: float, want: Configuration | None = None,
                   ) -> list[tuple[tuple[float, ...], Configuration]]:
    """The closed-form solutions (radians, each angle in (-pi, pi]) for a flange transform: all of them, or only
    those whose flags match ``want`` (a 0 in ``want`` accepts either choice; the singular wrist solution matches any).

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
        if want is not None and want.shoulder and shoulder != want.shoulder:
            continue
        d = max(-1.0, min(1.0, d))
        for elbow in (1, -1):
            if want is not None and want.elbow and elbow != want.elbow:
                continue
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
                if want is not None and want.wrist and wrist != want.wrist and sp >= WRIST_SINGULAR_SIN:
                    continue
                if sp < WRIST_SINGULAR_SIN and rw[2, 2] > 0:
                    # j5 ~ 0: J4 and J6 turn about (almost) the same axis, only j4 + j6 is well defined and the
                    # exact j4 swings with the slightest change. Keep j4 where it is and fit j5, j6 to the rest:
                    # Rz(-j4) rw = Ry(j5) Rz(j6) up to a tilt of at most sp about x.
                    if wrist == -1:
                        continue
                    fit = _rz(-j4_hint) @ rw
                    j4 = j4_hint
                    j5 = math.atan2(fit[0, 2], fit[2, 2])
                    j6 = math.atan2(fit[1, 0], fit[1, 1])
                    wrist = 0  # on the singularity: acceptable from either wrist configuration
                elif sp < 1e-9:
                    # j5 ~ 180 (beyond the Viper's J5 limits, kept for completeness): only j6 - j4 is defined.
                    if wrist == -1:
                        continue
                    j5 = math.atan2(sp, rw[2, 2])
                    j4 = j4_hint
                    j6 = j4 - math.atan2(rw[1, 0], -rw[0, 0])
                    wrist = 0
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


def _nearest_equivalent(angle_deg: float, ref_deg: float, lo: float, hi: float) -> float | None:
    """The equivalent of ``angle_deg`` (+k*360) inside [lo, hi] nearest to ``ref_deg``, or None if none is."""
    base = angle_deg + 360.0 * round((ref_deg - angle_deg) / 360.0)
    best: float | None = None
    for c in (base, base - 360.0, base + 360.0):
        if lo - 1e-6 <= c <= hi + 1e-6 and (best is None or abs(c - ref_deg) < abs(best - ref_deg)):
            best = c
    return best


WRIST_FREE_DEG = 5.0
"""Within this many degrees of J5 = 0 (the wrist singularity) the seed's FLIP/NOFLIP is not kept: both wrist
branches are candidates and the one nearest the seed wins, so J5 may pass through zero with J4 staying put instead
of J4 and J6 turning half a revolution to keep the sign of J5."""

SHOULDER_FREE_MM = 10.0
"""Within this distance of the wrist centre from the J1 axis the seed's LEFTY/RIGHTY is not kept (same reason)."""

ELBOW_FREE_DEG = 5.0
"""Within this many degrees of the stretched (or folded) elbow the seed's ABOVE/BELOW is not kept (same reason)."""


@dataclass(frozen=True, slots=True)
class JumpLimit:
    """How far one inverse-kinematics solution may move any joint, relative to the size of the Cartesian move.

    A target is refused with ``RobotError(JOINT_JUMP)`` when some joint would move more than::

        floor_deg + per_mm_deg * distance_mm + per_rot_deg * rotation_deg

    where ``distance_mm`` is how far the tool point moves (straight line, seed pose to target) and
    ``rotation_deg`` the angle of the rotation between the two tool orientations. With the defaults a 2 mm step
    may move no joint by more than 4 deg, a 1 deg turn of the tool no joint by more than 5 deg, while a deliberate
    move across the workspace is not limited in practice (300 mm allow 302 deg). Away from the singularities the Viper's joints
    move well under 1 deg per mm and about 1 deg per degree of tool rotation, so only the large joint motions that
    a small command should never cause are refused: a wrist flip, J4/J6 unwinding a revolution because the nearer
    equivalent is past a limit, J1 swinging round because the wrist passes near its axis.
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
"""The jump limit :func:`inverse` applies unless told otherwise (``jump=None`` turns it off)."""


def _free_configuration(cur: Sequence[float]) -> Configuration:
    """The seed's configuration with 0 (either choice) for each flag that is within its band of a singularity."""
    j2, j3 = math.radians(cur[1]), math.radians(cur[2])
    r, _ = _arm_plane(j2, j3)
    c3 = -math.cos(j3 - _BETA)
    s5 = math.sin(math.radians(cur[4]))
    return Configuration(
        shoulder=0 if abs(r) < SHOULDER_FREE_MM else (1 if r > 0 else -1),
        elbow=0 if abs(c3) < math.sin(math.radians(ELBOW_FREE_DEG)) else (1 if c3 > 0 else -1),
        wrist=0 if abs(s5) < math.sin(math.radians(WRIST_FREE_DEG)) else (1 if s5 > 0 else -1),
    )


def _matches(c: Configuration, want: Configuration) -> bool:
    return all(w == 0 or f == 0 or f == w for f, w in ((c.shoulder, want.shoulder), (c.elbow, want.elbow),
                                                        (c.wrist, want.wrist)))


@dataclass(frozen=True, slots=True)
class ConfigRequest:
    """A configuration the next motion must end in: V+ ``LEFTY``/``RIGHTY`` (``shoulder`` -1/+1), ``BELOW``/
    ``ABOVE`` (``elbow`` -1/+1), ``FLIP``/``NOFLIP`` (``wrist`` -1/+1), ``SINGLE`` (``single``: J6 within
    -180..180 deg). 0 (or False) leaves that choice to the seed, as without a request.

    Which sign is which V+ word is docs/vplus.md's "Configuration" (UNCONFIRMED for LEFTY/RIGHTY on this arm)."""

    shoulder: int = 0
    elbow: int = 0
    wrist: int = 0
    single: bool = False

    def changes(self, joints_deg: Sequence[float]) -> bool:
        """True if ``joints_deg`` is not in the requested configuration (a flag on its singularity matches)."""
        c = configuration(joints_deg)
        return not _matches(c, Configuration(self.shoulder, self.elbow, self.wrist))


def inverse(pose: Pose, current_joints_deg: Sequence[float], tool: Pose = NULL, *,
            limits: JointLimits = VIPER_S850_LIMITS,
            jump: JumpLimit | None = DEFAULT_JUMP_LIMIT,
            config: ConfigRequest | None = None) -> tuple[float, ...]:
    """Inverse kinematics: joints (deg) that put the tool at ``pose``, continuing from ``current_joints_deg``.

    Choice of solution, as V+ does it and then safer:

    - The arm keeps the configuration of the seed ``current_joints_deg`` (LEFTY/RIGHTY, ABOVE/BELOW, FLIP/NOFLIP).
      A flag whose seed is within its band of the singularity that separates the two choices
      (:data:`WRIST_FREE_DEG`, :data:`SHOULDER_FREE_MM`, :data:`ELBOW_FREE_DEG`) accepts either choice, so the arm
      can pass through the singularity continuously instead of flipping to keep the sign.
    - Among the solutions allowed, each with every joint's +-360 deg equivalents inside ``limits``, the one with
      the least total joint motion from the seed is taken.
    - On the wrist singularity (J5 = 0, within :data:`WRIST_SINGULAR_SIN`) only J4 + J6 is defined: J4 keeps the
      seed value and J6 takes the rotation (J5, J6 fitted; orientation error below ``WRIST_SINGULAR_SIN`` rad).
      Elsewhere ``forward(inverse(pose))`` is ``pose`` to rounding.
    - The chosen solution is then checked against ``jump`` (see :class:`JumpLimit`): if a joint would move more
      than the Cartesian size of the move (seed pose to ``pose``) justifies, the target is refused with
      ``RobotError(JOINT_JUMP)`` and nothing moves. ``jump=None`` turns the check off.

    - ``config`` (V+ ``LEFTY`` ... ``SINGLE``, :class:`ConfigRequest`): each flag it sets replaces the seed's, so the
      arm changes configuration during this motion; a change asked for is not a jump (the jump check is skipped
      when the request differs from the seed's configuration). ``single`` keeps J6 within -180..180 deg.

    Raises ``RobotError`` with ``OUT_OF_REACH`` when no allowed configuration reaches the pose, ``JOINT_LIMIT``
    when its solution lies outside the joint limits, ``JOINT_JUMP`` as above, ``ILLEGAL_VALUE`` for a pose that
    is not finite.
    """
    if len(current_joints_deg) != 6:
        raise ValueError(f"current_joints_deg: expected 6 values, got {len(current_joints_deg)}")
    cur = [float(v) for v in current_joints_deg]
    m = pose.to_matrix()
    if tool != NULL:
        m = m @ inverse_transform(tool.to_matrix())
    if not np.isfinite(m).all():
        raise RobotError(ErrorCode.ILLEGAL_VALUE, "location is not finite")
    want = _free_configuration(cur)
    changing = False
    lo, hi = limits.min_deg, limits.max_deg
    if config is not None:
        # a change asked for (another configuration, SINGLE unwinding J6) is not a jump nobody asked for
        changing = config.changes(cur) or (config.single and abs(cur[5]) > 180.0 + 1e-9)
        want = Configuration(config.shoulder or want.shoulder, config.elbow or want.elbow, config.wrist or want.wrist)
        if config.single:
            lo, hi = lo[:5] + (max(lo[5], -180.0),), hi[:5] + (min(hi[5], 180.0),)
    sols = _solutions_rad(m, math.radians(cur[3]), want)

    best: list[float] | None = None
    best_cost = math.inf
    matched_config = False
    for sol, c in sols:
        if not _matches(c, want):
            continue
        matched_config = True
        # Joints are independent in both the cost (a sum) and the limits (a box): take each joint's nearest
        # equivalent inside its limits. J2 and J3 can exceed (-180, 180] within the limits, hence all six.
        cand: list[float] = []
        for i in range(6):
            q = _nearest_equivalent(math.degrees(sol[i]), cur[i], lo[i], hi[i])
            if q is None:
                break
            cand.append(q)
        else:
            cost = sum(abs(a - b) for a, b in zip(cand, cur))
            if cost < best_cost:
                best, best_cost = cand, cost
    if best is None:
        if not matched_config:
            raise RobotError(ErrorCode.OUT_OF_REACH, "location out of range in the current configuration")
        # Report the limit the current-configuration solution breaks.
        for sol, c in sols:
            if _matches(c, want):
                deg = [math.degrees(a) for a in sol]
                limits.check([d + 360.0 * round((cur[i] - d) / 360.0) for i, d in enumerate(deg)])
        raise RobotError(ErrorCode.JOINT_LIMIT, "no solution within the joint limits")
    if jump is not None and not changing:
        _check_jump(best, cur, m, tool, limits, jump)
    return tuple(best)


def _check_jump(sol: list[float], cur: list[float], m_flange: np.ndarray, tool: Pose, limits: JointLimits,
                jump: JumpLimit) -> None:
    """Raise ``RobotError(JOINT_JUMP)`` when ``sol`` moves a joint more than ``jump`` allows for this move."""
    moves = [abs(a - b) for a, b in zip(sol, cur)]
    worst = max(range(6), key=moves.__getitem__)
    if moves[worst] <= jump.floor_deg:
        return  # within the floor whatever the Cartesian size: skip the forward kinematics
    seed = flange_matrix(cur)
    target = m_flange
    if tool != NULL:
        t = tool.to_matrix()
        seed, target = seed @ t, target @ t
    distance = float(np.linalg.norm(target[:3, 3] - seed[:3, 3]))
    r = seed[:3, :3].T @ target[:3, :3]
    # Axis-angle sine and cosine: atan2 stays precise for small angles, where acos(trace) loses half the digits.
    sin_rot = 0.5 * math.sqrt((r[2, 1] - r[1, 2]) ** 2 + (r[0, 2] - r[2, 0]) ** 2 + (r[1, 0] - r[0, 1]) ** 2)
    rotation = math.degrees(math.atan2(sin_rot, (float(r[0, 0] + r[1, 1] + r[2, 2]) - 1.0) / 2.0))
    allowed = jump.allowed_deg(distance, rotation)
    if moves[worst] <= allowed:
        return
    why = ""
    if worst in (3, 5) and abs(math.sin(math.radians(cur[4]))) < math.sin(math.radians(2 * WRIST_FREE_DEG)):
        why = "; wrist singularity"
    elif worst == 0 and abs(_arm_plane(math.radians(cur[1]), math.radians(cur[2]))[0]) < 10 * SHOULDER_FREE_MM:
        why = "; wrist near J1 axis"
    else:
        near = sol[worst] + 360.0 * round((cur[worst] - sol[worst]) / 360.0)
        if abs(near - cur[worst]) < moves[worst] - 1e-6 and limits.violations([*cur[:worst], near, *cur[worst + 1:]]):
            why = f"; {near:.1f} is past the limit"
    # Short: the error ack carries at most 80 characters of text.
    raise RobotError(ErrorCode.JOINT_JUMP, f"J{worst + 1} would turn {moves[worst]:.1f} deg for {distance:.2f} mm "
                                           f"{rotation:.2f} deg (max {allowed:.1f}){why}")


def check_joint_path(start_deg: Sequence[float], end_deg: Sequence[float], *,
                     limits: JointLimits = VIPER_S850_LIMITS) -> None:
    """Check a joint-interpolated path against the limits; raise ``RobotError(JOINT_LIMIT)`` if it leaves them.

    The limits form a box and a joint-interpolated path is a straight segment in joint space, so the segment lies
    inside the box exactly when both ends do: checking the ends checks every point of the path.
    """
    limits.check(start_deg)
    limits.check(end_deg)
