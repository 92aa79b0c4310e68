"""A straight line whose end no configuration of the arm reaches is refused as out of reach (-610) with the model's
reason, on every model, before anything moves: a shorter arm (the Viper s650) meets its stretched-arm singularity
on the way before the line leaves its reach, and that is not what is wrong with the line."""

from __future__ import annotations

import pytest

from aioadept.errors import RobotError
from aioadept.geometry import Pose
from aioadept.protocol import ErrorCode
from aioadept.robots import MODELS
from aioadept.sim.line import plan_tool_line


@pytest.mark.parametrize("name", sorted(MODELS))
def test_a_line_to_an_end_out_of_reach_is_refused_as_out_of_reach(name):
    m = MODELS[name]
    with pytest.raises(RobotError) as info:
        plan_tool_line(m.home_deg, Pose(2000.0, 0.0, 500.0, 0.0, 180.0, 0.0), model=m)
    assert info.value.code == ErrorCode.OUT_OF_REACH and "the line's end: location out of range" in info.value.message


@pytest.mark.parametrize("name", [n for n in sorted(MODELS) if MODELS[n].family == "scara"])
def test_a_scara_line_to_a_tilted_end_names_the_orientation(name):
    m = MODELS[name]
    home = m.forward(m.home_deg)
    with pytest.raises(RobotError, match="orientation not possible") as info:
        plan_tool_line(m.home_deg, Pose(home.x, home.y, home.z, 0.0, 170.0, 0.0), model=m)
    assert info.value.code == ErrorCode.OUT_OF_REACH
