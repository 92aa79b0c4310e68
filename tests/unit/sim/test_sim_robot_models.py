"""The simulated controller asks its robot model: home, joint limits, joint speeds and kinematics are the model's."""

from __future__ import annotations

import pytest

from aioadept.errors import RobotError
from aioadept.protocol import ErrorCode
from aioadept.robots import MODELS, model
from aioadept.sim.controller import Controller


def _run(gen) -> None:
    for _ in gen:
        pass


@pytest.mark.parametrize("name", sorted(MODELS))
def test_the_controller_starts_at_the_models_home_with_its_limits(name):
    m = model(name)
    ctl = Controller(model=m, instant=True)
    assert ctl.joints_deg == m.home_deg and ctl.joint_limits == m.limits
    assert ctl.here == m.forward(m.home_deg)
    assert ctl.trajectory.limits.max_speed_deg_s == m.max_speed_deg_s


@pytest.mark.parametrize("name", sorted(MODELS))
def test_a_single_joint_move_at_full_speed_takes_the_models_joint_speed(name):
    """J3 (the Cobra's quill, mm) or J6 moved alone at 100 %: distance / the model's speed, plus one ramp."""
    m = model(name)
    ctl = Controller(model=m)
    j = 2 if m.family == "scara" else 5
    target = list(m.home_deg)
    target[j] += 100.0
    _run(ctl.move_joints(target))
    ramp = ctl.trajectory.limits.ramp_s
    assert ctl.trajectory.t_rest_s == pytest.approx(100.0 / m.max_speed_deg_s[j] + ramp, rel=1e-6)


def test_a_cobra_controller_refuses_a_quill_past_its_stroke():
    m = model("cobra-s600")
    ctl = Controller(model=m, instant=True)
    target = list(m.home_deg)
    target[2] = m.limits.max_deg[2] + 1.0
    with pytest.raises(RobotError) as e:
        _run(ctl.move_joints(target))
    assert e.value.code == ErrorCode.JOINT_LIMIT and ctl.joints_deg == m.home_deg
