"""Motion timing of the simulated arm: synchronised trapezoidal joint profiles, blending and stopping.

Pure: every function takes the time as an argument (server-clock seconds), so the controller and its tests can
run motions without sleeping. The controller (:mod:`aioadept.sim.controller`) decides *when* a motion may start
(V+ forward processing); this module decides *how* the joints move once it has.

Model:

- **Joint interpolation.** A joint move is a straight segment in joint space (V+ ``MOVE``). All joints share one
  normalised trapezoidal profile, so they start and arrive together; the duration is that of the slowest joint.
- **Straight lines.** ``MOVES`` (and ``APPROS``, ``DEPARTS``) moves the tool on a straight line in Cartesian space,
  position linear and orientation on the shortest rotation (:mod:`aioadept.sim.line`, :class:`LineSegment`): the same
  trapezoid, on the path parameter; 100 % speed is :class:`CartesianLimits` (tool mm/s and deg/s), slowed down
  as a whole where a joint would exceed its own limit. A stop during a line decelerates along the line.
- **Speed.** The joint speed limits are the model's joint speeds times the speed fraction
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

from aioadept.robots.viper import VIPER_S850
from aioadept.sim.line import CartesianLimits, LinePath, line_duration


@dataclass(frozen=True, slots=True)
class MotionLimits:
    """Per-joint speed limits (deg/s at 100 %; mm/s for a prismatic joint) and the ramp time to full speed (s).
    The default is the Viper s850's; a controller of another model builds its own from ``model.max_speed_deg_s``."""

    max_speed_deg_s: tuple[float, ...] = VIPER_S850.max_speed_deg_s
    ramp_s: float = 0.1

    def __post_init__(self) -> None:
        if not self.max_speed_deg_s or min(self.max_speed_deg_s) <= 0:
            raise ValueError("max_speed_deg_s: expected a positive speed per joint")
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
            return np.zeros(len(v0))
        return v0 * tau - 0.5 * v0 * tau * tau / self.duration_s

    def velocity(self, t_s: float) -> np.ndarray:
        tau = max(t_s - self.t0_s, 0.0)
        if tau >= self.duration_s:
            return np.zeros(len(self.v0_deg_s))
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
    for d, vmax in zip(delta_deg, limits.max_speed_deg_s, strict=True):
        d = abs(d)
        if d == 0.0:
            continue
        v = vmax * speed_fraction
        a = v / ramp
        t = d / v + ramp if d >= v * ramp else 2.0 * math.sqrt(d / a)
        duration = max(duration, t)
    return duration, min(ramp, duration / 2.0)


def _at_least(duration_s: float, min_duration_s: float) -> float:
    """V+ DURATION: a motion shorter than ``min_duration_s`` is slowed to take that long (the same ramps, a lower
    cruise: "approximately" the duration, as the V+ Language Reference Guide's DURATION page says); a motion that
    does not move stays 0."""
    return max(duration_s, min_duration_s) if duration_s > 0 else duration_s


class Trajectory:
    """The arm's joint trajectory: where it is at any time, and the motions planned ahead.

    Segments overlap only when blended; the position is the start position plus the sum of every segment's
    offset, so blended motions superpose. Query times must not go back before the last :meth:`add` or
    :meth:`stop` (the controller only moves forward in time).
    """

    def __init__(self, joints_deg: Sequence[float], *, limits: MotionLimits = MotionLimits(),
                 time_scale: float = 1.0, instant: bool = False, cartesian: CartesianLimits | None = None) -> None:
        if len(joints_deg) != len(limits.max_speed_deg_s):
            raise ValueError(f"joints_deg: expected {len(limits.max_speed_deg_s)} values (one per joint speed)")
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
        v = np.zeros(len(self._base))
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
            accel_pct: float = 100.0, min_duration_s: float = 0.0) -> Segment:
        """Plan a joint move from :attr:`end_deg` to ``target_deg``, issued at ``t_s``.

        If a motion is still executing, the new one blends into it (starts as it begins to decelerate);
        otherwise it starts at ``t_s``. ``speed_pct`` is the effective speed (program x monitor, 0 < s <= 100).
        """
        self._fold(t_s)
        start = self.end_deg
        delta = np.subtract(target_deg, start)
        duration, ramp = plan_duration(delta, speed_pct / 100.0, limits=self.limits, accel_fraction=accel_pct / 100.0)
        duration = _at_least(duration, min_duration_s)
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

    def add_line(self, path: LinePath, t_s: float, *, speed_pct: float, accel_pct: float = 100.0,
                 min_duration_s: float = 0.0) -> Segment:
        """Plan a straight-line motion along ``path`` (from :func:`plan_line`, which must start at :attr:`end_deg`),
        issued at ``t_s``; blending and start time as :meth:`add`."""
        self._fold(t_s)
        if not np.allclose(path.start_deg, self.end_deg, atol=1e-6):
            raise ValueError("add_line: the path does not start where the planned motions end")
        duration, ramp = line_duration(path, speed_pct / 100.0, max_joint_speed_deg_s=self.limits.max_speed_deg_s,
                                       ramp_s=self.limits.ramp_s, cartesian=self.cartesian,
                                       accel_fraction=accel_pct / 100.0)
        duration = _at_least(duration, min_duration_s)
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


# -- straight-line segments (the line itself is planned in aioadept.sim.line) ------------------------------------

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
    ``duration_s``, so the tool comes to rest on the line it was given (a stop must not take the arm off its path;
    how far a real V+ controller strays while braking is UNCONFIRMED, docs/vplus.md)."""

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
            return np.zeros(self.path.joints_deg.shape[1])
        return self.path.slope(self._s(t_s)) * self.r0 * (1.0 - tau / self.duration_s)
