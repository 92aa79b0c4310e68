"""The straight-line planner's array path (aioadept.robots.viper_s850_batch, line._plan_batch) against the scalar
reference it replaces on the sim server's loop: the same closed-form solutions, the same choice from a seed, and the
same planned lines and refusals (code and text) on random lines and near each singularity. No sockets."""

from __future__ import annotations

import math

import numpy as np
import pytest

import aioadept.sim.line as line
from aioadept.errors import RobotError
from aioadept.geometry import Pose, decompose
from aioadept.robots import viper_s850 as kin
from aioadept.robots import viper_s850_batch as kb

LIMITS = kin.VIPER_S850_LIMITS
TOOL = Pose(0.0, 30.0, 120.0, 0.0, 20.0, 0.0)
A = Pose(400.0, -150.0, 400.0, 0.0, 180.0, 0.0)
B = Pose(400.0, 150.0, 400.0, 0.0, 180.0, 30.0)


def random_joints(rng: np.random.Generator, shrink: float = 1.0) -> list[float]:
    return [rng.uniform(lo * shrink, hi * shrink) for lo, hi in zip(LIMITS.min_deg, LIMITS.max_deg, strict=True)]


def both(start, target: Pose, tool: Pose = Pose()):
    """(reference, array) results of planning the line: each a LinePath or the RobotError it raised."""
    out = []
    for batch in (False, True):
        try:
            out.append(line.plan_tool_line(start, target, tool, batch=batch))
        except RobotError as exc:
            out.append(exc)
    return out


def assert_same(ref, got) -> str:
    if isinstance(ref, RobotError) or isinstance(got, RobotError):
        assert isinstance(ref, RobotError) and isinstance(got, RobotError), (ref, got)
        assert (got.code, got.message) == (ref.code, ref.message)
        return "refused"
    assert np.array_equal(got.s, ref.s)
    assert np.abs(got.joints_deg - ref.joints_deg).max() <= 1e-9
    return "planned"


@pytest.fixture
def scalar_calls(monkeypatch):
    """How many samples the array planner handed to the scalar inverse kinematics."""
    calls = []
    real = line._solve_sample

    def counting(*args, **kwargs):
        calls.append(args[3])
        return real(*args, **kwargs)

    monkeypatch.setattr(line, "_solve_sample", counting)
    return calls


def test_solutions_are_the_scalar_closed_form_branch_by_branch():
    rng = np.random.default_rng(3)
    compared = unreachable = 0
    for _ in range(400):
        m = kin.flange_matrix(random_joints(rng))
        m[:3, 3] *= rng.uniform(0.6, 1.6)  # some out of reach
        got = kb.solutions(m[None])
        if got.doubtful[0]:
            continue
        try:
            sols = kin._solutions_rad(m, 0.0)
        except RobotError:
            assert not got.reached[0].any()
            unreachable += 1
            continue
        seen = set()
        for sol, c in sols:
            i = kb.BRANCHES.index((c.shoulder, c.elbow, c.wrist))
            seen.add(i)
            np.testing.assert_allclose(got.joints_deg[0, i], np.degrees(sol), atol=1e-9)
        assert set(np.flatnonzero(got.reached[0])) == seen
        compared += 1
    assert compared > 200 and unreachable > 20


def test_choose_takes_what_inverse_takes_from_each_seed():
    rng = np.random.default_rng(5)
    seeds, targets = [], []
    for _ in range(600):
        q = random_joints(rng, 0.95)
        seeds.append(q)
        targets.append(np.array(q) + rng.normal(scale=rng.choice([0.5, 5.0, 40.0]), size=6))
    flange = np.stack([kin.flange_matrix(t) for t in targets])
    sols = kb.solutions(flange)
    got = kb.choose(np.array(seeds), sols.joints_deg, sols.reached, LIMITS)
    agreed = refused = 0
    for k, seed in enumerate(seeds):
        if sols.doubtful[k] or got.doubtful[k]:
            continue
        want = kin.inverse(decompose(flange[k]), seed, jump=None)
        np.testing.assert_allclose(got.joints_deg[k], want, atol=1e-9)
        agreed += 1
    for k in np.flatnonzero(got.branch == -1):
        with pytest.raises(RobotError):
            kin.inverse(decompose(flange[k]), seeds[k], jump=None)
        refused += 1
    assert agreed > 400 and refused > 5


@pytest.mark.parametrize(("tool", "window"), [(Pose(), line.BATCH_WINDOW), (TOOL, line.BATCH_WINDOW), (TOOL, 50)])
def test_random_lines_are_planned_and_refused_as_the_reference_does(tool, window, scalar_calls, monkeypatch):
    monkeypatch.setattr(line, "BATCH_WINDOW", window)  # 50: most lines take several windows
    rng = np.random.default_rng(7)
    seen = {"planned": 0, "refused": 0}
    for _ in range(60):
        q0 = random_joints(rng, 0.9)
        m0 = kin.flange_matrix(q0) @ tool.to_matrix()
        d = rng.normal(size=3)
        axis = rng.normal(size=3)
        m1 = m0.copy()
        m1[:3, 3] += d / np.linalg.norm(d) * rng.uniform(0.0, 600.0)
        m1[:3, :3] = m0[:3, :3] @ line._rot_exp(axis / np.linalg.norm(axis) * math.radians(rng.uniform(0, 120)))
        seen[assert_same(*both(q0, decompose(m1), tool))] += 1
    assert seen["planned"] >= 10 and seen["refused"] >= 10, seen
    # The array planner solves every sample of a line that is planned; a refusal's failing sample is scalar.
    assert len(scalar_calls) <= seen["refused"]


@pytest.mark.parametrize("centre", [
    (20.0, -60.0, 150.0, 30.0, 0.0, 10.0),                                    # wrist: J5 = 0
    (10.0, -60.0, math.degrees(math.atan2(90.0, 405.0)) + 90.0, 0.0, 60.0, 0.0),  # elbow stretched
    (0.0, -121.4, 150.0, 0.0, 60.0, 0.0),                                     # wrist centre on the J1 axis
])
def test_lines_around_each_singularity_are_planned_as_the_reference_does(centre):
    # Inside a configuration band either branch may be taken; across it the jump limit refuses: both as before.
    rng = np.random.default_rng(11)
    seen = {"planned": 0, "refused": 0}
    for i in range(40):
        tool = Pose() if i % 2 else TOOL
        qa = np.array(centre) + rng.normal(scale=4.0, size=6)
        qb = np.array(centre) + rng.normal(scale=4.0, size=6)
        seen[assert_same(*both(qa, kin.forward(qb, tool), tool))] += 1
    assert seen["planned"] >= 5, seen


@pytest.mark.parametrize("j5", [0.0, 0.003])
def test_a_line_on_the_wrist_singularity_is_solved_by_the_scalar_code_sample_by_sample(j5, scalar_calls):
    # J6 turning with J5 (almost) 0: every sample is the scalar code's special case (J4 kept from the seed, J5 and
    # J6 fitted), which the exact closed form would not give.
    start, end = (20.0, -60.0, 150.0, 30.0, j5, 10.0), (20.0, -60.0, 150.0, 30.5, j5, 30.0)
    ref, got = both(start, kin.forward(end))
    assert assert_same(ref, got) == "planned"
    assert len(scalar_calls) == len(ref.s) - 1
    assert np.ptp(got.joints_deg[:, 3]) < 1e-6, "J4 stays where it was (the closed form would turn it 0.5 deg)"


def test_an_ordinary_line_is_solved_without_the_scalar_code(scalar_calls):
    q0 = kin.inverse(A, kin.HOME_JOINTS_DEG)
    ref, got = both(q0, B)
    assert assert_same(ref, got) == "planned" and len(got.s) == 301
    assert scalar_calls == []


def test_a_refusal_names_the_same_sample_and_reason(scalar_calls):
    # Passing a joint limit part-way (J1 beyond 170 deg), as tests/unit/sim/test_straight_line.py.
    r, ang = 500.0, math.radians(160.0)
    start = kin.inverse(Pose(r * math.cos(ang), r * math.sin(ang), 400.0, 0.0, 180.0, 0.0), kin.HOME_JOINTS_DEG)
    ref, got = both(start, Pose(r * math.cos(ang), -r * math.sin(ang), 400.0, 0.0, 180.0, 0.0))
    assert assert_same(ref, got) == "refused" and "J1" in got.message
    assert len(scalar_calls) == 1, "only the failing sample"
