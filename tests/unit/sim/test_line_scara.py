"""A SCARA's straight lines solved in arrays (aioadept.sim.line._plan_scara) are the scalar planner's lines: the same
samples, the joints within 1e-9 (deg, mm), the same refusals; and the array planner does take the ordinary line."""

from __future__ import annotations

import numpy as np
import pytest

from aioadept.errors import RobotError
from aioadept.geometry import Pose
from aioadept.robots import model
from aioadept.sim import line

COBRAS = ["cobra-s600", "cobra-s800"]


def _plan(m, start, target, tool, batch):
    try:
        return line.plan_tool_line(start, target, tool, model=m, batch=batch)
    except RobotError as exc:
        return exc


@pytest.mark.parametrize("name", COBRAS)
def test_the_array_planner_takes_an_ordinary_line(name):
    m = model(name)
    start = m.home_deg
    here = m.forward(start)
    target = Pose(here.x - 100.0, here.y - 150.0, here.z + 30.0, 0.0, 180.0, here.roll + 20.0)
    start_m, target_m = m.flange_matrix(start), target.to_matrix()
    path = line._plan_scara(start, start_m, target_m, None, m, joint_limits=m.limits,
                            jump=line.DEFAULT_JUMP_LIMIT)
    assert path is not None and len(path.s) > 100
    np.testing.assert_allclose(m.flange_matrices(path.joints_deg[-1:])[0], target_m, atol=1e-9)


N_LINES = 48
"""Random lines per model (39 of 48 planned on both Cobras with this seed, the rest refused alike by both)."""


@pytest.mark.parametrize("name", COBRAS)
def test_random_lines_match_the_scalar_planner(name):
    m = model(name)
    rng = np.random.default_rng(7)
    lo, hi = np.array(m.limits.min_deg), np.array(m.limits.max_deg)
    tool = Pose(0.0, 15.0, 80.0, 0.0, 0.0, 25.0)
    used = 0
    for i in range(N_LINES):
        start = tuple(rng.uniform(lo, hi))
        goal = np.clip(np.array(start) + rng.normal(0.0, 40.0, 4) * (1, 1, 1.5, 3), lo, hi)
        target = m.forward(goal, tool if i % 2 else Pose())
        t = tool if i % 2 else Pose()
        fast, slow = _plan(m, start, target, t, True), _plan(m, start, target, t, False)
        if isinstance(slow, RobotError):
            assert isinstance(fast, RobotError) and (fast.code, fast.message) == (slow.code, slow.message)
            continue
        assert not isinstance(fast, RobotError), fast
        np.testing.assert_array_equal(fast.s, slow.s)
        np.testing.assert_allclose(fast.joints_deg, slow.joints_deg, rtol=0, atol=1e-9)
        start_m = m.flange_matrix(start) @ t.to_matrix()
        used += line._plan_scara(start, start_m, target.to_matrix(), None if t == Pose() else t.to_matrix(), m,
                                 joint_limits=m.limits, jump=line.DEFAULT_JUMP_LIMIT) is not None
    assert used >= N_LINES // 2, used
