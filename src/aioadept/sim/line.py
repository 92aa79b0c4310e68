"""Straight-line motion of the simulated arm (V+ ``MOVES``, ``APPROS``, ``DEPARTS``): the line's geometry, its
check along the whole length, and its timing.

Pure: no clock, no I/O. :class:`aioadept.sim.motion.Trajectory` runs a planned line (``LineSegment``), the
controller (:meth:`aioadept.sim.controller.Controller.move_line`) plans it with :func:`plan_tool_line`.

A straight line is planned once, when its instruction runs: the tool's path (position linear, orientation turning
on the shortest rotation about one fixed axis, slerp) is sampled every :data:`LINE_STEP_MM` / :data:`LINE_STEP_DEG`
and each sample is solved with the inverse kinematics, continuing from the previous one: all samples at once in
numpy arrays (:func:`_plan_batch`, :mod:`aioadept.robots.viper_s850_batch`), because the plan runs on the sim
server's event loop and a ``stop`` read meanwhile waits for it; :func:`plan_line` is the one-sample-at-a-time
reference it gives the same result as. Any sample out of reach,
past a joint limit, or whose joints jump (a configuration change or a swing through a singularity) refuses the
whole line before anything moves. The joints between two samples are interpolated linearly: the samples are so
close that the tool stays within micrometres of the line (tests/unit/sim/test_straight_line.py measures it).
Timing is the same trapezoid as a joint move, on the path parameter s in [0, 1].
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from aioadept.errors import RobotError
from aioadept.geometry import NULL, Pose, decompose, inverse_transform
from aioadept.protocol import ErrorCode
from aioadept.robots import RobotModel, all_solutions
from aioadept.robots import viper_s850_batch as kb
from aioadept.robots.base import DEFAULT_JUMP_LIMIT, JointLimits, JumpLimit
from aioadept.robots import scara
from aioadept.robots.scara import Scara
from aioadept.robots.viper import VIPER_S850, Viper


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

    ``max_speed_mm_s``: the tool tip's linear speed at 100 % (about 2000 mm/s, a value usual for this arm class; UNCONFIRMED for the Viper);
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
    return _line_pose(m0, m1, _rot_log(m0[:3, :3].T @ m1[:3, :3]), s)


def _line_pose(m0: np.ndarray, m1: np.ndarray, turn: np.ndarray, s: float) -> np.ndarray:
    """:func:`line_pose_matrix` with the turn (rotation vector from m0 to m1, in m0's frame) computed once."""
    m = np.eye(4)
    m[:3, 3] = m0[:3, 3] + s * (m1[:3, 3] - m0[:3, 3])
    m[:3, :3] = m0[:3, :3] @ _rot_exp(s * turn)
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


def _sample_count(length_mm: float, rotation_deg: float, step_mm: float, step_deg: float) -> int:
    n = max(1, math.ceil(length_mm / step_mm), math.ceil(rotation_deg / step_deg))
    return min(n, LINE_MAX_SAMPLES)


def _fail_at(exc: RobotError, s: float, length: float) -> RobotError:
    """The sample's error with where along the line it failed (the ack's text holds 80 characters: keep it short)."""
    return RobotError(exc.code, f"line {s * length:.0f}/{length:.0f} mm: {exc.message}")


def plan_line(start_deg: Sequence[float], target_m: np.ndarray, *,
              solve: Callable[[np.ndarray, tuple[float, ...]], Sequence[float]], line_start_m: np.ndarray,
              step_mm: float = LINE_STEP_MM, step_deg: float = LINE_STEP_DEG) -> LinePath:
    """Sample the straight line from ``line_start_m`` (the tool pose at ``start_deg``) to ``target_m`` and solve
    every sample with ``solve(m, seed_deg) -> joints_deg`` (the inverse kinematics, continuing from ``seed_deg``;
    it raises for a sample that cannot be reached). Pure: the kinematics come in as ``solve``.

    One call of ``solve`` per sample: the reference that :func:`plan_tool_line`'s array planner is checked and
    benchmarked against (``plan_tool_line(..., batch=False)`` plans with this).

    Raises :class:`aioadept.errors.RobotError` with the code ``solve`` raised for the first sample that fails
    (``OUT_OF_REACH``, ``JOINT_LIMIT``, ``JOINT_JUMP``) and where along the line it is.
    """
    length = float(np.linalg.norm(target_m[:3, 3] - line_start_m[:3, 3]))
    turn = _rot_log(line_start_m[:3, :3].T @ target_m[:3, :3])
    rotation = math.degrees(float(np.linalg.norm(turn)))
    n = _sample_count(length, rotation, step_mm, step_deg)
    s = np.linspace(0.0, 1.0, n + 1)
    joints = np.empty((n + 1, len(start_deg)))
    joints[0] = start_deg
    seed = tuple(float(v) for v in start_deg)
    for k in range(1, n + 1):
        m = target_m if k == n else _line_pose(line_start_m, target_m, turn, float(s[k]))
        try:
            seed = tuple(solve(m, seed))
        except RobotError as exc:
            raise _fail_at(exc, float(s[k]), length) from exc
        joints[k] = seed
    return LinePath(s, joints, length, rotation, line_start_m.copy(), target_m.copy())


def _line_poses(m0: np.ndarray, m1: np.ndarray, turn: np.ndarray, s: np.ndarray) -> np.ndarray:
    """:func:`_line_pose` at every ``s`` (K,) at once: (K, 4, 4); an ``s`` of 1 gives ``m1`` itself."""
    out = np.zeros((len(s), 4, 4))
    out[:, :3, 3] = m0[:3, 3] + s[:, None] * (m1[:3, 3] - m0[:3, 3])
    out[:, 3, 3] = 1.0
    angle = float(np.linalg.norm(turn))
    r0 = m0[:3, :3]
    if angle < 1e-15:
        out[:, :3, :3] = r0
    else:
        k = turn / angle
        kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        a = s * angle
        # R0 @ (I + sin(a) K + (1 - cos(a)) K^2), Rodrigues as _rot_exp
        out[:, :3, :3] = (r0 + np.sin(a)[:, None, None] * (r0 @ kx)
                          + (1.0 - np.cos(a))[:, None, None] * (r0 @ (kx @ kx)))
    out[s >= 1.0] = m1
    return out


BATCH_MIN_SAMPLES = 16
"""Lines with fewer samples are solved one sample at a time: the array planner's fixed cost is not worth it."""
BATCH_WINDOW = 1024
"""Samples solved per pass of the array planner (every line inside the Viper's workspace fits in two)."""
_MAX_SHORT_RUNS = 16
"""Checks of a guess that fail before the end of their window (each costs a pass over the rest of it) before the
array planner solves the rest of the line one sample at a time: its cost stays within a few passes of the
reference loop's, whatever the line."""


def _plan_batch(start_deg: Sequence[float], start_m: np.ndarray, target_m: np.ndarray, tool_m: np.ndarray | None,
                solve: Callable[[np.ndarray, tuple[float, ...]], Sequence[float]], *,
                joint_limits: JointLimits, jump: JumpLimit, model: Viper = VIPER_S850) -> LinePath | None:
    """:func:`plan_line` with the samples solved in arrays (:mod:`aioadept.robots.viper_s850_batch`); the same
    samples, joints to rounding, and the same refusals. None: too few samples, plan with :func:`plan_line`.

    The inverse kinematics continue from the previous sample, a chain; it is solved by guessing and checking. The
    guess: the branch the first sample takes, each joint unwrapped to stay continuous. The check, for all samples
    at once: ``choose`` from the guessed previous sample takes that same solution, and the step passes the jump
    limit. Up to the first sample where the check fails (or is in doubt) the guess is what the one-by-one loop
    computes; that sample is solved with the scalar ``solve`` (which raises the reference's error, if any), and the
    guessing starts again from it. The samples are solved :data:`BATCH_WINDOW` at a time.
    """
    length = float(np.linalg.norm(target_m[:3, 3] - start_m[:3, 3]))
    turn = _rot_log(start_m[:3, :3].T @ target_m[:3, :3])
    rotation = math.degrees(float(np.linalg.norm(turn)))
    n = _sample_count(length, rotation, LINE_STEP_MM, LINE_STEP_DEG)
    if n < BATCH_MIN_SAMPLES:
        return None
    s = np.linspace(0.0, 1.0, n + 1)
    inv_tool = None if tool_m is None else inverse_transform(tool_m)
    joints = np.empty((n + 1, len(start_deg)))
    joints[0] = start_deg
    k = hi = 0  # joints[:k + 1] are planned; sample k + 1 is next; the window holds samples lo + 1 .. hi
    short_runs = 0
    while k < n and short_runs <= _MAX_SHORT_RUNS:
        if k == hi:
            # The next window: a refusal part-way does not pay for solving the whole of a long line first.
            lo, hi = k, min(n, k + BATCH_WINDOW)
            poses = _line_poses(start_m, target_m, turn, s[lo + 1:hi + 1])
            sols = kb.solutions(poses if inv_tool is None else poses @ inv_tool, model)
        i = k - lo
        if not sols.doubtful[i]:
            first = kb.choose(joints[k:k + 1], sols.joints_deg[i:i + 1], sols.reached[i:i + 1], joint_limits, model)
            if not first.doubtful[0]:
                k += _check_run(joints, k, int(first.branch[0]), sols, i, poses, tool_m, joint_limits, jump, model)
                if k == hi:
                    continue
                short_runs += 1
        k += 1  # sample k + 1 by the scalar inverse kinematics, as the reference loop does
        joints[k] = _solve_sample(solve, poses[k - 1 - lo], joints[k - 1], float(s[k]), length)
    for j in range(k + 1, n + 1):
        m = target_m if j == n else _line_pose(start_m, target_m, turn, float(s[j]))
        joints[j] = _solve_sample(solve, m, joints[j - 1], float(s[j]), length)
    return LinePath(s, joints, length, rotation, start_m.copy(), target_m.copy())


def _solve_sample(solve: Callable[[np.ndarray, tuple[float, ...]], Sequence[float]], m: np.ndarray,
                  seed: np.ndarray, s: float, length: float) -> tuple[float, ...]:
    try:
        return tuple(solve(m, tuple(float(v) for v in seed)))
    except RobotError as exc:
        raise _fail_at(exc, s, length) from exc


def _check_run(joints: np.ndarray, k: int, branch: int, sols: kb.Solutions, i: int, poses: np.ndarray,
               tool_m: np.ndarray | None, joint_limits: JointLimits, jump: JumpLimit, model: Viper) -> int:
    """Guess the samples from k + 1 to the end of the window on ``branch``, continuing from ``joints[k]``, check
    them, write the run that holds into ``joints``; return its length (0 when the guess fails at once). ``sols``
    and ``poses`` are the window's, sample k + 1 at index ``i``."""
    a = sols.joints_deg[i:, branch]  # (K, 6), each angle in (-180, 180]
    # Unwrapped from joints[k]: the equivalent of each sample nearest the one before (what choose re-checks).
    turns = np.round((np.vstack([joints[k:k + 1], a[:-1]]) - a) / 360.0)
    guess = a + 360.0 * np.cumsum(turns, axis=0)
    seeds = np.vstack([joints[k:k + 1], guess[:-1]])
    got = kb.choose(seeds, sols.joints_deg[i:], sols.reached[i:], joint_limits, model)
    good = (~got.doubtful & ~sols.doubtful[i:] & (got.branch == branch)
            & (np.abs(got.joints_deg - guess) <= kb.DOUBT).all(axis=1))
    # The jump limit, as _check_jump: within the floor, or within what the Cartesian size of the step allows.
    moved = np.abs(got.joints_deg - seeds).max(axis=1)
    big = np.flatnonzero(good & (moved > jump.floor_deg - kb.DOUBT))
    if len(big):
        seed_m = model.flange_matrices(seeds[big])
        if tool_m is not None:
            seed_m = seed_m @ tool_m
        allowed = kb.jump_allowed_deg(seed_m, poses[i + big], jump)
        good[big] = moved[big] < allowed - kb.DOUBT
    bad = np.flatnonzero(~good)
    f = int(bad[0]) if len(bad) else len(good)
    joints[k + 1:k + 1 + f] = got.joints_deg[:f]
    return f


def _plan_scara(start_deg: Sequence[float], start_m: np.ndarray, target_m: np.ndarray, tool_m: np.ndarray | None,
                model: Scara, *, joint_limits: JointLimits, jump: JumpLimit) -> LinePath | None:
    """:func:`plan_line` for a SCARA with every sample solved at once, or None: leave the line to the scalar
    planner (too few samples, or any decision within :data:`~aioadept.robots.viper_s850_batch.DOUBT` of where the
    scalar inverse could decide otherwise or refuse). On a SCARA the scalar inverse keeps the seed's arm (RIGHTY,
    LEFTY) away from the stretched arm and takes each joint's equivalent nearest the previous sample: so the whole
    line is the seed's branch unwrapped continuously, when every sample is reached, keeps clear of the stretched
    arm's band, lies within the limits and passes the jump limit. Anything else is the scalar planner's to refuse."""
    length = float(np.linalg.norm(target_m[:3, 3] - start_m[:3, 3]))
    turn = _rot_log(start_m[:3, :3].T @ target_m[:3, :3])
    rotation = math.degrees(float(np.linalg.norm(turn)))
    n = _sample_count(length, rotation, LINE_STEP_MM, LINE_STEP_DEG)
    if n < BATCH_MIN_SAMPLES:
        return None
    s = np.linspace(0.0, 1.0, n + 1)
    poses = _line_poses(start_m, target_m, turn, s[1:])
    sols, reached = model.all_solutions(poses if tool_m is None else poses @ inverse_transform(tool_m))
    band = math.sin(math.radians(scara.ELBOW_FREE_DEG)) + kb.DOUBT
    start = np.asarray(start_deg, dtype=float)
    s2 = math.sin(math.radians(start[1]))
    if not reached.all() or abs(s2) < band:
        return None
    a = sols[:, 0 if s2 > 0 else 1]
    if (np.abs(np.sin(np.radians(a[:, 1]))) < band).any():
        return None  # a sample in the stretched arm's band: there the scalar inverse may change arms
    rev = ~np.array(model.prismatic)
    q = (np.vstack([start, a[:-1]]) - a) / 360.0
    turns = np.where(rev, np.round(q), 0.0)
    if (rev & (np.abs(np.abs(q - np.round(q)) - 0.5) < kb.DOUBT)).any():
        return None  # two equivalents equally near
    joints = np.vstack([start, a + 360.0 * np.cumsum(turns, axis=0)])
    lo, hi = np.asarray(joint_limits.min_deg) - 1e-6, np.asarray(joint_limits.max_deg) + 1e-6
    if ((joints[1:] < lo + kb.DOUBT) | (joints[1:] > hi - kb.DOUBT)).any():
        return None  # past a limit: the scalar inverse refuses, or takes another equivalent and jumps
    moved = np.abs(np.diff(joints, axis=0)).max(axis=1)
    big = np.flatnonzero(moved > jump.floor_deg - kb.DOUBT)
    if len(big):
        seed_m = model.flange_matrices(joints[big])
        if tool_m is not None:
            seed_m = seed_m @ tool_m
        if (moved[big] >= kb.jump_allowed_deg(seed_m, poses[big], jump) - kb.DOUBT).any():
            return None
    return LinePath(s, joints, length, rotation, start_m.copy(), target_m.copy())


def line_duration(path: LinePath, speed_fraction: float, *, max_joint_speed_deg_s: Sequence[float], ramp_s: float,
                  cartesian: CartesianLimits = CartesianLimits(), accel_fraction: float = 1.0) -> tuple[float, float]:
    """(duration_s, ramp_s) of a straight line at ``speed_fraction`` (0..1]: a trapezoid on the path parameter
    whose cruise rate keeps the tool within the Cartesian speed, its turn within the rotational speed, and every
    joint within its own maximum speed (``max_joint_speed_deg_s``, whatever the speed; ``ramp_s`` the ramp time at full
    acceleration, as :class:`aioadept.sim.motion.MotionLimits`). Robot time, before any time scale."""
    if not 0.0 < speed_fraction <= 1.0 + 1e-9:
        raise ValueError(f"speed_fraction: {speed_fraction} outside (0, 1]")
    if not 0.0 < accel_fraction <= 1.0 + 1e-9:
        raise ValueError(f"accel_fraction: {accel_fraction} outside (0, 1]")
    ramp = ramp_s / accel_fraction
    # The time each limit needs at constant speed, for the whole path (s from 0 to 1).
    needs = [path.length_mm / (cartesian.max_speed_mm_s * speed_fraction),
             path.rotation_deg / (cartesian.max_rot_speed_deg_s * speed_fraction)]
    # The joints are bounded by their own maximum speeds, not scaled by SPEED: for a straight line SPEED sets the
    # tool's speed, and a joint limits it only where the line needs that joint faster than it can go.
    needs += list(path.max_slope / np.asarray(max_joint_speed_deg_s))
    cruise = max(needs)
    if cruise <= 0.0:
        return 0.0, 0.0
    # As plan_duration: cruise + ramp when the ramps fit, else a triangle with the same acceleration.
    duration = cruise + ramp if cruise >= ramp else 2.0 * math.sqrt(cruise * ramp)
    return duration, min(ramp, duration / 2.0)


def plan_tool_line(start_deg: Sequence[float], pose: Pose, tool: Pose = NULL, *,
                   joint_limits: JointLimits | None = None, jump: JumpLimit | None = DEFAULT_JUMP_LIMIT,
                   batch: bool = True, model: RobotModel = VIPER_S850) -> LinePath:
    """The straight line of the tool (``tool`` in the flange frame, V+ ``TOOL``) from the joints ``start_deg`` to
    ``pose``, every sample solved with ``model``'s inverse kinematics (``joint_limits`` default: the model's); raises ``RobotError`` (``OUT_OF_REACH``,
    ``JOINT_LIMIT``, ``JOINT_JUMP``: a swing through a singularity, or ``ILLEGAL_VALUE``) naming where along the
    line, before anything moves.

    The jump limit always applies to a line's samples (the default one when ``jump`` is None): with samples 1 mm
    apart it is what tells a singularity from an ordinary turn of the joints.

    The samples are solved in arrays (a 300 mm line in about 1 ms; it runs on the sim server's event loop, where a
    ``stop`` waits for it). ``batch=False``: one scalar inverse kinematics per sample (:func:`plan_line`), the
    reference the array planner gives the same result as (to rounding: joints within 1e-9 deg, the same refusals).
    A SCARA's line is solved in arrays when nothing about it is in doubt (:func:`_plan_scara`), else sample by
    sample.
    """
    limits = model.limits if joint_limits is None else joint_limits
    start_m = model.flange_matrix(start_deg)
    if tool != NULL:
        start_m = start_m @ tool.to_matrix()
    target_m = pose.to_matrix()
    if not np.isfinite(target_m).all():
        raise RobotError(ErrorCode.ILLEGAL_VALUE, "location is not finite")
    step_jump = jump if jump is not None else DEFAULT_JUMP_LIMIT
    end_flange = target_m if tool == NULL else target_m @ inverse_transform(tool.to_matrix())
    if not all_solutions(model, end_flange[None])[1].any():
        # An end no configuration reaches is out of range whatever the line passes first (a shorter arm meets the
        # stretched-arm singularity on the way before the line leaves its reach): the error is the end's, with the
        # model's reason (out of reach, a SCARA's orientation).
        try:
            model.inverse(pose, start_deg, tool, limits=limits, jump=None)
        except RobotError as exc:
            raise RobotError(ErrorCode.OUT_OF_REACH, f"the line's end: {exc.message}") from exc
        raise RobotError(ErrorCode.OUT_OF_REACH, "location out of range (the line's end)")

    def solve(m: np.ndarray, seed: tuple[float, ...]) -> tuple[float, ...]:
        sample = decompose(m)
        try:
            return model.inverse(sample, seed, tool, limits=limits, jump=step_jump)
        except RobotError as exc:
            if exc.code != ErrorCode.JOINT_JUMP:
                raise
            # Between two samples 1 mm apart a joint jumps: either it would have to pass its limit (the nearer
            # way round is past it) or the line crosses a singularity. Say which.
            q = model.inverse(sample, seed, tool, limits=limits, jump=None)
            worst = max(range(len(q)), key=lambda i: abs(q[i] - seed[i]))
            near = q[worst] + 360.0 * round((seed[worst] - q[worst]) / 360.0)
            if abs(near - seed[worst]) < abs(q[worst] - seed[worst]) - 1e-6 and limits.violations(
                    [*seed[:worst], near, *seed[worst + 1:]]):
                raise RobotError(ErrorCode.JOINT_LIMIT, f"J{worst + 1} {near:.1f} past its limit") from exc
            why = exc.message.rpartition("; ")[2] if "; " in exc.message else "singularity"
            raise RobotError(ErrorCode.JOINT_JUMP, f"J{worst + 1} jumps {abs(q[worst] - seed[worst]):.1f} deg "
                                                   f"in a step: {why}") from exc

    tool_m = None if tool == NULL else tool.to_matrix()
    if batch and isinstance(model, Viper):
        path = _plan_batch(start_deg, start_m, target_m, tool_m, solve, joint_limits=limits, jump=step_jump,
                           model=model)
        if path is not None:
            return path
    elif batch:
        path = _plan_scara(start_deg, start_m, target_m, tool_m, model, joint_limits=limits, jump=step_jump)
        if path is not None:
            return path
    return plan_line(start_deg, target_m, solve=solve, line_start_m=start_m)
