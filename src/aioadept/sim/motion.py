"""Motion timing of the simulated arm: synchronised trapezoidal joint profiles, blending and stopping.

Pure: every function takes the time as an argument (server-clock seconds), so the controller and its tests can
run motions without sleeping. The controller (:mod:`aioadept.sim.controller`) decides *when* a motion may start
(V+ forward processing); this module decides *how* the joints move once it has.

Model:

- **Joint interpolation.** A joint move is a straight segment in joint space (V+ ``MOVE``). All joints share one
  normalised trapezoidal profile, so they start and arrive together; the duration is that of the slowest joint.
- **Straight lines.** ``MOVES`` (and ``APPROS``, ``DEPARTS``) moves the tool on a straight line in Cartesian space,
  position linear and orientation on the shortest rotation (:func:`plan_line`, :class:`LineSegment`): the same
  trapezoid, on the path parameter; 100 % speed is :class:`CartesianLimits` (tool mm/s and deg/s), slowed down
  as a whole where a joint would exceed its own limit. A stop during a line decelerates along the line.
- **Speed.** The joint speed limits are ``MAX_JOINT_SPEED_DEG_S`` times the speed fraction
  (program speed x monitor speed). With ``SCALE.ACCEL`` (on, as V+ defaults) the acceleration limits scale the same
  way, so the ramp time stays at ``ramp_s`` (0.1 s by default: a_max = v_max / 0.1 s).
- **Blending.** A motion added while another is executing starts when the previous one begins to decelerate: the
  deceleration of one overlaps the acceleration of the next and the velocities add, the continuous path V+ makes
  of consecutive motions without ``BREAK``.
- **Stop.** Each joint's velocity ramps down linearly to zero, all joints together, in the time the most loaded
  joint needs at full acceleration.
- **Time scale.** Durations are divided by ``time_scale``; ``instant`` makes every motion take no time.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aioadept.errors import RobotError
from aioadept.robots.viper_s850 import MAX_JOINT_SPEED_DEG_S


@dataclass(frozen=True, slots=True)
class MotionLimits:
    """Per-joint speed limits (deg/s at 100 %) and the ramp time to full speed (s)."""

    max_speed_deg_s: tuple[float, ...] = MAX_JOINT_SPEED_DEG_S
    ramp_s: float = 0.1

    def __post_init__(self) -> None:
        if len(self.max_speed_deg_s) != 6 or min(self.max_speed_deg_s) <= 0:
            raise ValueError("max_speed_deg_s: expected 6 positive speeds")
        if self.ramp_s <= 0:
            raise ValueError("ramp_s: must be > 0")


@dataclass(frozen=True, slots=True)
class Segment:
    """One joint-interpolated motion: ``delta_deg`` traversed from ``t0_s`` in ``duration_s``.

    The profile accelerates for ``ramp_s``, cruises, and decelerates for ``ramp_s`` (``ramp_s <= duration_s/2``).
    ``speed_pct`` is the effective speed it was planned with (program x monitor).
    """

    start_deg: tuple[float, ...]
    end_deg: tuple[float, ...]
    t0_s: float
    duration_s: float
    ramp_s: float
    speed_pct: float

    @property
    def t_end_s(self) -> float:
        return self.t0_s + self.duration_s

    @property
    def delta_deg(self) -> np.ndarray:
        return np.subtract(self.end_deg, self.start_deg)

    def progress(self, t_s: float) -> float:
        """Normalised position along the segment, 0 before it starts and 1 after it ends."""
        tau = t_s - self.t0_s
        T, ta = self.duration_s, self.ramp_s
        if tau >= T:
            return 1.0
        if tau <= 0.0:
            return 0.0
        vp = 1.0 / (T - ta)
        if tau < ta:
            return 0.5 * vp * tau * tau / ta
        if tau <= T - ta:
            return vp * (tau - 0.5 * ta)
        rem = T - tau
        return 1.0 - 0.5 * vp * rem * rem / ta

    def rate(self, t_s: float) -> float:
        """Time derivative of :meth:`progress` (1/s)."""
        tau = t_s - self.t0_s
        T, ta = self.duration_s, self.ramp_s
        if tau <= 0.0 or tau >= T:
            return 0.0
        vp = 1.0 / (T - ta)
        if tau < ta:
            return vp * tau / ta
        if tau <= T - ta:
            return vp
        return vp * (T - tau) / ta

    def offset(self, t_s: float) -> np.ndarray:
        return self.delta_deg * self.progress(t_s)

    def velocity(self, t_s: float) -> np.ndarray:
        return self.delta_deg * self.rate(t_s)


@dataclass(frozen=True, slots=True)
class StopSegment:
    """Deceleration to rest: velocity ``v0_deg_s`` at ``t0_s`` falls linearly to zero at ``t0_s + duration_s``."""

    start_deg: tuple[float, ...]
    v0_deg_s: tuple[float, ...]
    t0_s: float
    duration_s: float

    @property
    def t_end_s(self) -> float:
        return self.t0_s + self.duration_s

    @property
    def end_deg(self) -> tuple[float, ...]:
        return tuple(float(v) for v in np.add(self.start_deg, self.offset(self.t_end_s)))

    @property
    def speed_pct(self) -> float:
        return 0.0

    def offset(self, t_s: float) -> np.ndarray:
        tau = min(max(t_s - self.t0_s, 0.0), self.duration_s)
        v0 = np.asarray(self.v0_deg_s)
        if self.duration_s <= 0.0:
            return np.zeros(6)
        return v0 * tau - 0.5 * v0 * tau * tau / self.duration_s

    def velocity(self, t_s: float) -> np.ndarray:
        tau = max(t_s - self.t0_s, 0.0)
        if tau >= self.duration_s:
            return np.zeros(6)
        return np.asarray(self.v0_deg_s) * (1.0 - tau / self.duration_s)


def plan_duration(delta_deg: Sequence[float], speed_fraction: float, *, limits: MotionLimits = MotionLimits(),
                  accel_fraction: float = 1.0) -> tuple[float, float]:
    """(duration_s, ramp_s) of a synchronised trapezoid covering ``delta_deg`` at ``speed_fraction`` (0..1].

    ``accel_fraction`` is V+ ``ACCEL``/100: below 1 the ramps get longer. Robot time, before any time scale.
    """
    if not 0.0 < speed_fraction <= 1.0 + 1e-9:
        raise ValueError(f"speed_fraction: {speed_fraction} outside (0, 1]")
    if not 0.0 < accel_fraction <= 1.0 + 1e-9:
        raise ValueError(f"accel_fraction: {accel_fraction} outside (0, 1]")
    ramp = limits.ramp_s / accel_fraction
    duration = 0.0
    for d, vmax in zip(delta_deg, limits.max_speed_deg_s):
        d = abs(d)
        if d == 0.0:
            continue
        v = vmax * speed_fraction
        a = v / ramp
        t = d / v + ramp if d >= v * ramp else 2.0 * math.sqrt(d / a)
        duration = max(duration, t)
    return duration, min(ramp, duration / 2.0)


class Trajectory:
    """The arm's joint trajectory: where it is at any time, and the motions planned ahead.

    Segments overlap only when blended; the position is the start position plus the sum of every segment's
    offset, so blended motions superpose. Query times must not go back before the last :meth:`add` or
    :meth:`stop` (the controller only moves forward in time).
    """

    def __init__(self, joints_deg: Sequence[float], *, limits: MotionLimits = MotionLimits(),
                 time_scale: float = 1.0, instant: bool = False, cartesian: CartesianLimits | None = None) -> None:
        if len(joints_deg) != 6:
            raise ValueError("joints_deg: expected 6 values")
        if not time_scale > 0:
            raise ValueError("time_scale: must be > 0")
        self.limits = limits
        self.cartesian = cartesian if cartesian is not None else CartesianLimits()
        """What 100 % means for straight-line motions (tool speed and turn rate)."""
        self.time_scale = float(time_scale)
        self.instant = instant
        self._base = np.array(joints_deg, dtype=float)
        self._base_t = tuple(float(v) for v in self._base)  # at rest this is the answer; no arrays needed
        self._segments: list[Segment | StopSegment] = []

    # -- queries ---------------------------------------------------------------------------------------------
    def position(self, t_s: float) -> tuple[float, ...]:
        """Joint angles (deg) at ``t_s``."""
        if not self._segments:
            return self._base_t
        p = self._base.copy()
        for seg in self._segments:
            p += seg.offset(t_s)
        return tuple(float(v) for v in p)

    def velocity(self, t_s: float) -> tuple[float, ...]:
        """Joint velocities (deg/s, real time) at ``t_s``."""
        v = np.zeros(6)
        for seg in self._segments:
            if isinstance(seg, StopSegment) or seg.t0_s < t_s < seg.t_end_s:
                v += seg.velocity(t_s)
        return tuple(float(x) for x in v)

    @property
    def end_deg(self) -> tuple[float, ...]:
        """Where the robot will be when every planned motion is done (the start of the next one)."""
        if not self._segments:
            return tuple(float(v) for v in self._base)
        return self._segments[-1].end_deg

    @property
    def t_rest_s(self) -> float:
        """When every planned motion is done (-inf when nothing was ever planned)."""
        return max((s.t_end_s for s in self._segments), default=-math.inf)

    def in_motion(self, t_s: float) -> bool:
        return t_s < self.t_rest_s

    def pending_start_s(self, t_s: float) -> float | None:
        """Start time of a motion planned but not yet started at ``t_s`` (V+: one motion queued ahead)."""
        for seg in self._segments:
            if seg.t0_s > t_s:
                return seg.t0_s
        return None

    def ready_s(self) -> float | None:
        """When a new motion may be issued so that it starts at once: when the last planned motion begins to
        decelerate (it blends in there), or when a stop comes to rest. None when nothing is planned."""
        if not self._segments:
            return None
        last = self._segments[-1]
        return last.t_end_s - getattr(last, "ramp_s", 0.0)

    def current_speed_pct(self, t_s: float) -> float | None:
        """Effective speed of the motion executing at ``t_s`` (the latest started), or None at rest."""
        speed = None
        for seg in self._segments:
            if seg.t0_s <= t_s < seg.t_end_s:
                speed = seg.speed_pct
        return speed

    # -- changes ---------------------------------------------------------------------------------------------
    def _fold(self, t_s: float) -> None:
        """Fold segments finished by ``t_s`` into the base position, so the list stays short."""
        keep: list[Segment | StopSegment] = []
        for seg in self._segments:
            if seg.t_end_s <= t_s and not keep:
                self._base = self._base + seg.offset(seg.t_end_s)
            else:
                keep.append(seg)
        self._segments = keep
        self._base_t = tuple(float(v) for v in self._base)

    def add(self, target_deg: Sequence[float], t_s: float, *, speed_pct: float,
            accel_pct: float = 100.0) -> Segment:
        """Plan a joint move from :attr:`end_deg` to ``target_deg``, issued at ``t_s``.

        If a motion is still executing, the new one blends into it (starts as it begins to decelerate);
        otherwise it starts at ``t_s``. ``speed_pct`` is the effective speed (program x monitor, 0 < s <= 100).
        """
        self._fold(t_s)
        start = self.end_deg
        delta = np.subtract(target_deg, start)
        duration, ramp = plan_duration(delta, speed_pct / 100.0, limits=self.limits, accel_fraction=accel_pct / 100.0)
        if self.instant:
            duration, ramp = 0.0, 0.0
        else:
            duration, ramp = duration / self.time_scale, ramp / self.time_scale
        t0 = t_s
        if self._segments:
            last = self._segments[-1]
            if last.t_end_s > t_s:
                overlap = min(getattr(last, "ramp_s", 0.0), ramp)
                t0 = max(t_s, last.t_end_s - overlap)
        seg = Segment(tuple(start), tuple(float(v) for v in target_deg), t0, duration, ramp, float(speed_pct))
        self._segments.append(seg)
        return seg

    def add_line(self, path: LinePath, t_s: float, *, speed_pct: float, accel_pct: float = 100.0) -> Segment:
        """Plan a straight-line motion along ``path`` (from :func:`plan_line`, which must start at :attr:`end_deg`),
        issued at ``t_s``; blending and start time as :meth:`add`."""
        self._fold(t_s)
        if not np.allclose(path.start_deg, self.end_deg, atol=1e-6):
            raise ValueError("add_line: the path does not start where the planned motions end")
        duration, ramp = line_duration(path, speed_pct / 100.0, limits=self.limits, cartesian=self.cartesian,
                                       accel_fraction=accel_pct / 100.0)
        if self.instant:
            duration, ramp = 0.0, 0.0
        else:
            duration, ramp = duration / self.time_scale, ramp / self.time_scale
        t0 = t_s
        if self._segments:
            last = self._segments[-1]
            if last.t_end_s > t_s:
                overlap = min(getattr(last, "ramp_s", 0.0), ramp)
                t0 = max(t_s, last.t_end_s - overlap)
        seg = LineSegment(path.start_deg, path.end_deg, t0, duration, ramp, float(speed_pct), path)
        self._segments.append(seg)
        return seg

    def _stop_on_line(self, t_s: float) -> float | None:
        """When a straight line is the only motion under way at ``t_s`` (nothing blending into or out of it),
        decelerate along it and return the time of rest; else None (the caller stops joint by joint)."""
        moving = [seg for seg in self._segments if seg.t0_s < t_s < seg.t_end_s]
        if len(moving) != 1 or not isinstance(moving[0], (LineSegment, LineStopSegment)):
            return None
        seg = moving[0]
        if isinstance(seg, LineSegment):
            s0, r0 = seg.progress(t_s), seg.rate(t_s)
        else:
            tau = t_s - seg.t0_s
            s0, r0 = seg._s(t_s), seg.r0 * (1.0 - tau / seg.duration_s)
        p0 = self.position(t_s)
        path = seg.path
        if r0 <= 0.0:
            return None
        # Rest as soon as the most loaded joint (at full acceleration) and the tool (at the Cartesian acceleration
        # the ramp implies) allow: the same rule as a joint stop, measured in robot time.
        sc = self.time_scale
        a_max = np.array(self.limits.max_speed_deg_s) / self.limits.ramp_s
        t_joint = float(np.max(np.abs(path.slope(s0) * r0 / sc) / a_max))
        t_cart = path.length_mm * r0 / sc / (self.cartesian.max_speed_mm_s / self.limits.ramp_s)
        duration = max(t_joint, t_cart) / sc
        if duration <= 0.0:
            return None
        self._base = np.array(p0)
        self._base_t = tuple(p0)
        self._segments = [LineStopSegment(path, s0, r0, t_s, duration)]
        return t_s + duration

    def stop(self, t_s: float) -> float:
        """Decelerate to rest from ``t_s``, dropping motions not yet reached; returns the time of rest.

        A straight line under way on its own stops along the line; anything else stops joint by joint."""
        if not self.instant:
            t_rest = self._stop_on_line(t_s)
            if t_rest is not None:
                return t_rest
        p0 = self.position(t_s)
        v0 = np.array(self.velocity(t_s))
        self._base = np.array(p0)
        self._base_t = tuple(p0)
        self._segments = []
        if self.instant or not np.any(v0):
            return t_s
        # Robot-time velocities and full accelerations a = v_max / ramp; scaled back to real time.
        s = self.time_scale
        a_max = np.array(self.limits.max_speed_deg_s) / self.limits.ramp_s
        t_stop_robot = float(np.max(np.abs(v0 / s) / a_max))
        duration = t_stop_robot / s
        self._segments.append(StopSegment(tuple(p0), tuple(float(v) for v in v0), t_s, duration))
        return t_s + duration


# -- straight-line motion (V+ MOVES, APPROS, DEPARTS) ------------------------------------------------------------
#
# A straight line is planned once, when its instruction runs: the tool's path (position linear, orientation turning
# on the shortest rotation about one fixed axis, slerp) is sampled every LINE_STEP_MM / LINE_STEP_DEG and each
# sample is solved with the inverse kinematics, continuing from the previous one. Any sample out of reach, past a
# joint limit, or whose joints jump (a configuration change or a swing through a singularity) refuses the whole
# line before anything moves. The joints between two samples are interpolated linearly: the samples are so close
# that the tool stays within micrometres of the line (tests/unit/sim/test_straight_line.py measures it).
# Timing is the same trapezoid as a joint move, on the path parameter s in [0, 1].

LINE_STEP_MM = 1.0
"""Largest distance between two samples of a straight line (mm)."""
LINE_STEP_DEG = 0.5
"""Largest rotation of the tool between two samples of a straight line (deg)."""
LINE_MAX_SAMPLES = 10_000
"""A line longer than this many steps is sampled more coarsely (10 m at 1 mm; beyond the Viper's workspace)."""


@dataclass(frozen=True, slots=True)
class CartesianLimits:
    """What 100 % speed means for a straight-line motion (V+ ``SPEED``: "motion speed has different meanings for
    joint-interpolated motions and straight-line motions").

    ``max_speed_mm_s``: the tool tip's linear speed at 100 % (FACTS.md: about 2000 mm/s for this arm class);
    ``max_rot_speed_deg_s``: the tool's rotational speed at 100 % (V+'s ``r_speed_factor`` scales it; the value
    for the Viper is UNCONFIRMED, docs/vplus.md). The joints' own speed limits apply too: where the line needs a
    joint faster than its limit, the whole line is slowed down, so the path never changes.
    """

    max_speed_mm_s: float = 2000.0
    max_rot_speed_deg_s: float = 360.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.max_speed_mm_s) and self.max_speed_mm_s > 0):
            raise ValueError("max_speed_mm_s: must be a finite number > 0")
        if not (math.isfinite(self.max_rot_speed_deg_s) and self.max_rot_speed_deg_s > 0):
            raise ValueError("max_rot_speed_deg_s: must be a finite number > 0")


def _rot_log(r: np.ndarray) -> np.ndarray:
    """Rotation vector (axis x angle, radians) of a rotation matrix; the angle is in [0, pi]."""
    cos_a = max(-1.0, min(1.0, (float(np.trace(r)) - 1.0) / 2.0))
    w = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    sin_a = 0.5 * float(np.linalg.norm(w))
    angle = math.atan2(sin_a, cos_a)
    if angle < 1e-12:
        return np.zeros(3)
    if sin_a > 1e-6:
        return w / (2.0 * sin_a) * angle
    # Half a turn: the axis is the column of (R + I)/2 with the largest norm (either sign is the shortest rotation).
    b = (r + np.eye(3)) / 2.0
    k = int(np.argmax(np.diag(b)))
    axis = b[:, k] / math.sqrt(max(b[k, k], 1e-300))
    return axis / np.linalg.norm(axis) * angle


def _rot_exp(v: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    angle = float(np.linalg.norm(v))
    if angle < 1e-15:
        return np.eye(3)
    k = v / angle
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * (kx @ kx)


def line_pose_matrix(m0: np.ndarray, m1: np.ndarray, s: float) -> np.ndarray:
    """The tool's 4x4 pose at ``s`` (0..1) along the straight line from ``m0`` to ``m1``: position linear,
    orientation on the shortest rotation from one to the other (slerp)."""
    if s <= 0.0:
        return m0.copy()
    if s >= 1.0:
        return m1.copy()
    m = np.eye(4)
    m[:3, 3] = m0[:3, 3] + s * (m1[:3, 3] - m0[:3, 3])
    m[:3, :3] = m0[:3, :3] @ _rot_exp(s * _rot_log(m0[:3, :3].T @ m1[:3, :3]))
    return m


@dataclass(frozen=True, slots=True, eq=False)
class LinePath:
    """A planned straight line: joint samples ``joints_deg[k]`` at path parameters ``s[k]`` (0 .. 1).

    ``length_mm`` and ``rotation_deg`` are the tool's travel and turn; ``start_m``/``end_m`` its 4x4 poses.
    """

    s: np.ndarray
    joints_deg: np.ndarray
    length_mm: float
    rotation_deg: float
    start_m: np.ndarray
    end_m: np.ndarray

    @property
    def start_deg(self) -> tuple[float, ...]:
        return tuple(float(v) for v in self.joints_deg[0])

    @property
    def end_deg(self) -> tuple[float, ...]:
        return tuple(float(v) for v in self.joints_deg[-1])

    def _bracket(self, s: float) -> tuple[int, float]:
        n = len(self.s) - 1
        if s <= 0.0:
            return 0, 0.0
        if s >= 1.0:
            return n - 1, 1.0
        k = min(int(np.searchsorted(self.s, s, side="right")) - 1, n - 1)
        return k, (s - self.s[k]) / (self.s[k + 1] - self.s[k])

    def joints_at(self, s: float) -> np.ndarray:
        """Joint angles (deg) at path parameter ``s`` (clamped to 0..1)."""
        k, f = self._bracket(s)
        return self.joints_deg[k] + f * (self.joints_deg[k + 1] - self.joints_deg[k])

    def slope(self, s: float) -> np.ndarray:
        """d(joints)/ds (deg per unit of s) at ``s``."""
        k, _ = self._bracket(s)
        return (self.joints_deg[k + 1] - self.joints_deg[k]) / (self.s[k + 1] - self.s[k])

    @property
    def max_slope(self) -> np.ndarray:
        """The largest |d(joint)/ds| of each joint along the line."""
        d = np.abs(np.diff(self.joints_deg, axis=0)) / np.diff(self.s)[:, None]
        return d.max(axis=0)


def plan_line(start_deg: Sequence[float], target_m: np.ndarray, *, solve, line_start_m: np.ndarray,
              step_mm: float = LINE_STEP_MM, step_deg: float = LINE_STEP_DEG) -> LinePath:
    """Sample the straight line from ``line_start_m`` (the tool pose at ``start_deg``) to ``target_m`` and solve
    every sample with ``solve(m, seed_deg) -> joints_deg`` (the inverse kinematics, continuing from ``seed_deg``;
    it raises for a sample that cannot be reached). Pure: the kinematics come in as ``solve``.

    Raises :class:`aioadept.errors.RobotError` with the code ``solve`` raised for the first sample that fails
    (``OUT_OF_REACH``, ``JOINT_LIMIT``, ``JOINT_JUMP``) and where along the line it is.
    """
    length = float(np.linalg.norm(target_m[:3, 3] - line_start_m[:3, 3]))
    rotation = math.degrees(float(np.linalg.norm(_rot_log(line_start_m[:3, :3].T @ target_m[:3, :3]))))
    n = max(1, math.ceil(length / step_mm), math.ceil(rotation / step_deg))
    n = min(n, LINE_MAX_SAMPLES)
    s = np.linspace(0.0, 1.0, n + 1)
    joints = np.empty((n + 1, 6))
    joints[0] = start_deg
    seed = tuple(float(v) for v in start_deg)
    for k in range(1, n + 1):
        m = line_pose_matrix(line_start_m, target_m, float(s[k]))
        try:
            seed = tuple(solve(m, seed))
        except RobotError as exc:
            # Same code, and where along the line it failed (the ack's text holds 80 characters: keep it short).
            raise RobotError(exc.code, f"line {float(s[k]) * length:.0f}/{length:.0f} mm: {exc.message}") from exc
        joints[k] = seed
    return LinePath(s, joints, length, rotation, line_start_m.copy(), target_m.copy())


def line_duration(path: LinePath, speed_fraction: float, *, limits: MotionLimits = MotionLimits(),
                  cartesian: CartesianLimits = CartesianLimits(), accel_fraction: float = 1.0) -> tuple[float, float]:
    """(duration_s, ramp_s) of a straight line at ``speed_fraction`` (0..1]: a trapezoid on the path parameter
    whose cruise rate keeps the tool within the Cartesian speed, its turn within the rotational speed, and every
    joint within its own speed limit. Robot time, before any time scale."""
    if not 0.0 < speed_fraction <= 1.0 + 1e-9:
        raise ValueError(f"speed_fraction: {speed_fraction} outside (0, 1]")
    if not 0.0 < accel_fraction <= 1.0 + 1e-9:
        raise ValueError(f"accel_fraction: {accel_fraction} outside (0, 1]")
    ramp = limits.ramp_s / accel_fraction
    # The time each limit needs at constant speed, for the whole path (s from 0 to 1).
    needs = [path.length_mm / (cartesian.max_speed_mm_s * speed_fraction),
             path.rotation_deg / (cartesian.max_rot_speed_deg_s * speed_fraction)]
    needs += list(path.max_slope / (np.asarray(limits.max_speed_deg_s) * speed_fraction))
    cruise = max(needs)
    if cruise <= 0.0:
        return 0.0, 0.0
    # As plan_duration: cruise + ramp when the ramps fit, else a triangle with the same acceleration.
    duration = cruise + ramp if cruise >= ramp else 2.0 * math.sqrt(cruise * ramp)
    return duration, min(ramp, duration / 2.0)


@dataclass(frozen=True, slots=True)
class LineSegment(Segment):
    """A straight-line motion: :class:`Segment` timing on the path parameter, joints from ``path``."""

    path: LinePath

    def offset(self, t_s: float) -> np.ndarray:
        return self.path.joints_at(self.progress(t_s)) - np.asarray(self.start_deg)

    def velocity(self, t_s: float) -> np.ndarray:
        return self.path.slope(self.progress(t_s)) * self.rate(t_s)


@dataclass(frozen=True, slots=True)
class LineStopSegment:
    """Deceleration to rest along a straight line: the path rate ``r0`` (1/s) at ``s0`` falls linearly to zero in
    ``duration_s``, so the tool stops on the line (V+: a stop during ``MOVES`` does not leave the path)."""

    path: LinePath
    s0: float
    r0: float
    t0_s: float
    duration_s: float

    @property
    def t_end_s(self) -> float:
        return self.t0_s + self.duration_s

    @property
    def start_deg(self) -> tuple[float, ...]:
        return tuple(float(v) for v in self.path.joints_at(self.s0))

    def _s(self, t_s: float) -> float:
        tau = min(max(t_s - self.t0_s, 0.0), self.duration_s)
        if self.duration_s <= 0.0:
            return self.s0
        return self.s0 + self.r0 * tau - 0.5 * self.r0 * tau * tau / self.duration_s

    @property
    def end_deg(self) -> tuple[float, ...]:
        return tuple(float(v) for v in self.path.joints_at(self._s(self.t_end_s)))

    @property
    def speed_pct(self) -> float:
        return 0.0

    def offset(self, t_s: float) -> np.ndarray:
        return self.path.joints_at(self._s(t_s)) - self.path.joints_at(self.s0)

    def velocity(self, t_s: float) -> np.ndarray:
        tau = max(t_s - self.t0_s, 0.0)
        if tau >= self.duration_s:
            return np.zeros(6)
        return self.path.slope(self._s(t_s)) * self.r0 * (1.0 - tau / self.duration_s)
