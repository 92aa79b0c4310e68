"""A Viper's inverse kinematics over many poses at once (numpy arrays), for the straight-line planner.

Pure numpy, no I/O. :func:`aioadept.sim.line.plan_tool_line` solves a line's hundreds of samples with these
instead of calling :func:`aioadept.robots.viper_s850.inverse` once per sample (about 36 us each; a 300 mm line
held the sim server's event loop 10-24 ms). They are the scalar functions' formulas written over arrays, in the same
order, so they choose the same solution; where a choice is within :data:`DOUBT` of its threshold (a configuration
band's edge, a joint limit, two solutions almost as near, the jump limit) or the scalar code takes a special case
(the wrist or the J1 axis singularity, the edge of the reach), they say so and the caller solves that sample with
the scalar :func:`~aioadept.robots.viper_s850.inverse`: every decision is the scalar code's, to rounding
(tests/unit/sim/test_line_batch.py compares the two on random lines).

- :func:`solutions`: the eight closed-form solutions of each flange pose (``_solutions_rad``, all branches).
- :func:`choose`: which of them ``inverse`` takes from each seed (configuration kept, nearest equivalents within
  the limits, least total motion).
- :func:`jump_allowed_deg`: the :class:`~aioadept.robots.viper_s850.JumpLimit` allowance of each step.
- :func:`flange_matrices`: forward kinematics of many joint vectors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aioadept.robots import viper as kin
from aioadept.robots.base import JointLimits, JumpLimit
from aioadept.robots.viper import VIPER_S850, Viper

BRANCHES: tuple[tuple[int, int, int], ...] = tuple(
    (sh, el, wr) for sh in (1, -1) for el in (1, -1) for wr in (1, -1))
"""(shoulder, elbow, wrist) of each of the eight solutions, in ``_solutions_rad``'s order (its tie-break order)."""
_SH, _EL, _WR = (np.array([b[i] for b in BRANCHES]) for i in range(3))

DOUBT = 1e-9
"""A decision whose quantity is this close to its threshold (mm, deg, or a sine) is left to the scalar code: the
array functions round differently from ``math`` in the last bits, so only a choice this near a tie could differ."""


@dataclass(frozen=True, slots=True, eq=False)
class Solutions:
    """The closed-form solutions of N flange poses.

    ``joints_deg`` (N, 8, 6): each angle in (-180, 180], branch order :data:`BRANCHES`; ``reached`` (N, 8): the
    branch's shoulder reaches the wrist centre; ``doubtful`` (N,): solve that pose with the scalar code (the wrist
    within 2x ``WRIST_SINGULAR_SIN`` of J5 = 0, where J4 follows the seed; the wrist centre on the J1 axis; a
    reach test within :data:`DOUBT`).
    """

    joints_deg: np.ndarray
    reached: np.ndarray
    doubtful: np.ndarray


def _wrap(a: np.ndarray) -> np.ndarray:
    """Into (-pi, pi], for angles in (-3 pi, 3 pi] (``_wrap_pi``'s atan2(sin, cos) to rounding, cheaper)."""
    return np.where(a > np.pi, a - 2.0 * np.pi, np.where(a <= -np.pi, a + 2.0 * np.pi, a))


def solutions(flange: np.ndarray, model: Viper = VIPER_S850) -> Solutions:
    """All eight solutions of each 4x4 flange pose in ``flange`` (N, 4, 4), as ``_solutions_rad`` computes them.

    The branches are array axes (shoulder, elbow, wrist), so the work is a fixed number of numpy calls."""
    A1_MM, D1_MM, A2_MM, D6_MM, _L3_MM, _BETA = model.a1, model.d1, model.a2, model.d6, model.l3, model.beta  # noqa: N806
    n = len(flange)
    rot = flange[:, :3, :3]
    wc = flange[:, :3, 3] - D6_MM * rot[:, :, 2]
    rho = np.hypot(wc[:, 0], wc[:, 1])
    v = (wc[:, 2] - D1_MM)[:, None]
    two = np.array([1.0, -1.0])
    out = np.empty((n, 2, 2, 2, 6))
    # axis 1: shoulder +1, -1. j1 = atan2(+-y, +-x), so its cosine and sine are +-(x, y) / rho.
    j1 = np.arctan2(two * wc[:, 1:2], two * wc[:, 0:1])
    with np.errstate(invalid="ignore", divide="ignore"):  # rho = 0 (on the J1 axis) is doubtful anyway
        c1, s1 = two * (wc[:, 0] / rho)[:, None], two * (wc[:, 1] / rho)[:, None]
    u = two * rho[:, None] - A1_MM
    d = (u * u + v * v - A2_MM ** 2 - _L3_MM ** 2) / (2.0 * A2_MM * _L3_MM)
    ok = np.abs(d) <= 1.0 + 1e-9
    asin = np.arcsin(np.clip(d, -1.0, 1.0))
    # axis 2: elbow +1 (the branch of home), -1
    j3 = np.stack([np.pi - asin, asin], axis=-1) + _BETA
    ang = np.pi / 2 - j3 + _BETA
    j2 = _wrap(np.arctan2(_L3_MM * np.sin(ang), A2_MM + _L3_MM * np.cos(ang)) - np.arctan2(v, u)[..., None])
    j3 = _wrap(j3)
    # rw = Ry(-(j2 + j3)) @ Rz(-j1) @ rot, the rotation the wrist makes: only the entries j4, j5, j6 are read from
    c23, s23 = np.cos(j2 + j3), np.sin(j2 + j3)
    a0 = [(c1 * rot[:, None, 0, i] + s1 * rot[:, None, 1, i])[..., None] for i in range(3)]  # (Rz(-j1) rot)[0, i]
    rw02 = c23 * a0[2] - s23 * rot[:, None, None, 2, 2]
    rw20, rw21, rw22 = (s23 * a0[i] + c23 * rot[:, None, None, 2, i] for i in range(3))
    rw12 = (-s1 * rot[:, None, 0, 2] + c1 * rot[:, None, 1, 2])[..., None]
    sp = np.hypot(rw20, rw21)
    # axis 3: wrist +1 (sin j5 > 0), -1: the other wrist solution is (j4 + 180, -j5, j6 + 180)
    j5 = np.arctan2(sp, rw22)
    j4 = np.arctan2(rw12, rw02)  # in (-pi, pi]: wrapping is a no-op
    j6 = np.arctan2(rw21, -rw20)
    out[..., 0] = j1[:, :, None, None]
    out[..., 1] = j2[..., None]
    out[..., 2] = j3[..., None]
    out[..., 0, 3], out[..., 1, 3] = j4, np.where(j4 > 0.0, j4 - np.pi, j4 + np.pi)
    out[..., 0, 4], out[..., 1, 4] = j5, -j5
    out[..., 0, 5], out[..., 1, 5] = j6, np.where(j6 > 0.0, j6 - np.pi, j6 + np.pi)
    reached = np.broadcast_to(ok[:, :, None, None], (n, 2, 2, 2)).reshape(n, 8)
    doubtful = ((rho < 1e-6) | (np.abs(np.abs(d) - (1.0 + 1e-9)) < DOUBT).any(axis=1)
                # the wrist singularity: there J4 follows the seed, the scalar code's special case
                | ((sp < 2.0 * kin.WRIST_SINGULAR_SIN) & ok[..., None]).any(axis=(1, 2)))
    np.degrees(out, out=out)
    return Solutions(out.reshape(n, 8, 6), reached.copy(), doubtful)


@dataclass(frozen=True, slots=True, eq=False)
class Choice:
    """What :func:`choose` found for each of M (seed, pose) pairs.

    ``branch`` (M,): index into :data:`BRANCHES` (-1: none); ``joints_deg`` (M, 6): the solution as ``inverse``
    returns it (before its jump check); ``doubtful`` (M,): leave it to the scalar code (a tie within
    :data:`DOUBT`, or no solution at all: the scalar code raises the right error).
    """

    branch: np.ndarray
    joints_deg: np.ndarray
    doubtful: np.ndarray


def choose(seeds_deg: np.ndarray, sols: np.ndarray, reached: np.ndarray, limits: JointLimits,
           model: Viper = VIPER_S850) -> Choice:
    """The solution :func:`~aioadept.robots.viper_s850.inverse` takes for pose k from ``seeds_deg[k]`` (M, 6),
    given its solutions ``sols`` (M, 8, 6) and ``reached`` (M, 8) from :func:`solutions`: the seed's configuration
    (each flag free within its band of the singularity), every joint at its equivalent nearest the seed within
    ``limits``, the least total motion; the first branch wins a tie. Every seed must lie within ``limits``."""
    A1_MM, A2_MM, A3_MM, D4_MM, _BETA = model.a1, model.a2, model.a3, model.d4, model.beta  # noqa: N806
    m = len(seeds_deg)
    rad = np.radians(seeds_deg)
    j2, j3 = rad[:, 1], rad[:, 2]
    r = A1_MM + A2_MM * np.cos(j2) - A3_MM * np.cos(j2 + j3) + D4_MM * np.sin(j2 + j3)
    c3 = -np.cos(j3 - _BETA)
    s5 = np.sin(rad[:, 4])
    sin_elbow, sin_wrist = math.sin(math.radians(kin.ELBOW_FREE_DEG)), math.sin(math.radians(kin.WRIST_FREE_DEG))
    match = reached.copy()
    for x, band, flag in ((r, kin.SHOULDER_FREE_MM, _SH), (c3, sin_elbow, _EL), (s5, sin_wrist, _WR)):
        want = np.where(np.abs(x) < band, 0, np.sign(x))
        match &= (want[:, None] == 0) | (want[:, None] == flag[None, :])
    doubtful = ((np.abs(np.abs(r) - kin.SHOULDER_FREE_MM) < DOUBT) | (np.abs(np.abs(c3) - sin_elbow) < DOUBT)
                | (np.abs(np.abs(s5) - sin_wrist) < DOUBT))

    # Only the solutions in the wanted configuration (one per seed, away from the bands) are worked on.
    rows, cols = np.nonzero(match)
    ref = seeds_deg[rows]
    a = sols[rows, cols]
    # Each joint's equivalent (+k*360) nearest the seed within the limits, as _nearest_equivalent: base is the
    # nearest of all; when it is past a limit, only the one 360 deg back towards the seed (which is within the
    # limits) can be inside them.
    lo, hi = np.asarray(limits.min_deg) - 1e-6, np.asarray(limits.max_deg) + 1e-6
    q = (ref - a) / 360.0
    turns = np.round(q)
    base = a + 360.0 * turns
    equiv = np.where(base > hi, base - 360.0, np.where(base < lo, base + 360.0, base))
    found = ((equiv >= lo) & (equiv <= hi)).all(axis=1)
    unsure = ((np.abs(base - lo) < DOUBT) | (np.abs(base - hi) < DOUBT) | (np.abs(equiv - lo) < DOUBT)
              | (np.abs(equiv - hi) < DOUBT) | (np.abs(np.abs(q - turns) - 0.5) < DOUBT)).any(axis=1)
    doubtful[rows[unsure]] = True

    moved = np.abs(equiv - ref)
    # summed joint by joint in order, as the scalar code's sum()
    cost = np.full((m, 8), np.inf)
    cost[rows, cols] = np.where(found, moved[:, 0] + moved[:, 1] + moved[:, 2] + moved[:, 3] + moved[:, 4]
                                + moved[:, 5], np.inf)
    at = np.zeros((m, 8), dtype=np.intp)
    at[rows, cols] = np.arange(len(rows))
    branch = np.argmin(cost, axis=1)
    every = np.arange(m)
    best = cost[every, branch]
    cost[every, branch] = np.inf
    none = ~np.isfinite(best)
    best = np.where(none, 0.0, best)
    doubtful |= none | (cost.min(axis=1) - best <= DOUBT * (1.0 + best))  # a runner-up within DOUBT
    joints = equiv[at[every, branch]] if len(rows) else np.zeros((m, 6))
    return Choice(np.where(none, -1, branch), joints, doubtful)


def flange_matrices(joints_deg: np.ndarray, model: Viper = VIPER_S850) -> np.ndarray:
    """4x4 flange transforms (M, 4, 4) of joint vectors (M, 6) in degrees: :meth:`Viper.flange_matrices`."""
    return model.flange_matrices(joints_deg)


def jump_allowed_deg(seed_tool: np.ndarray, target_tool: np.ndarray, jump: JumpLimit) -> np.ndarray:
    """The largest joint motion (deg) :class:`~aioadept.robots.viper_s850.JumpLimit` allows for each move from the
    tool pose ``seed_tool[k]`` to ``target_tool[k]`` (M, 4, 4): as ``_check_jump`` measures the move."""
    distance = np.linalg.norm(target_tool[:, :3, 3] - seed_tool[:, :3, 3], axis=1)
    r = np.swapaxes(seed_tool[:, :3, :3], 1, 2) @ target_tool[:, :3, :3]
    sin_rot = 0.5 * np.sqrt((r[:, 2, 1] - r[:, 1, 2]) ** 2 + (r[:, 0, 2] - r[:, 2, 0]) ** 2
                            + (r[:, 1, 0] - r[:, 0, 1]) ** 2)
    rotation = np.degrees(np.arctan2(sin_rot, (r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2] - 1.0) / 2.0))
    return jump.floor_deg + jump.per_mm_deg * distance + jump.per_rot_deg * rotation


__all__ = ["BRANCHES", "DOUBT", "Choice", "Solutions", "choose", "flange_matrices", "jump_allowed_deg", "solutions"]
