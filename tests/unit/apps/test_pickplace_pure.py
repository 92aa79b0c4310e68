"""Pick and place's pure parts: the tool-down pose and its heading, the grip's half-turn fold, the workspace check,
the locate answer read from the bus attributes (bad answers as clear errors), the slots checked before any motion."""

from __future__ import annotations

import math

import pytest

from aioadept.bus.located import LocatedPart
from aioadept.apps.pickplace import (
    PickPlaceParams,
    check_workspace,
    fold_heading,
    on_feeder,
    parts_of,
    slot_targets,
    tool_down,
)
from aioadept.errors import PickPlaceError
from aioadept.world import Feeder, Pallet


@pytest.mark.parametrize("heading", [0.0, 10.0, -75.0, 90.0, 179.0, -180.0])
def test_tool_down_points_down_with_its_x_axis_along_the_heading(heading):
    m = tool_down(400.0, 50.0, 100.0, heading).to_matrix()
    assert m[2, 2] == pytest.approx(-1.0)
    got = math.degrees(math.atan2(m[1, 0], m[0, 0]))
    assert (got - heading + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("h, folded", [(10.0, 10.0), (100.0, -80.0), (-135.0, 45.0), (180.0, 0.0), (90.0, -90.0)])
def test_fold_heading_keeps_a_two_finger_grip_within_90_deg(h, folded):
    assert fold_heading(h) == pytest.approx(folded)


def test_the_workspace_check_names_the_target_and_the_limits():
    p = PickPlaceParams(min_radius_mm=300.0, max_radius_mm=700.0, min_z_mm=0.0, max_z_mm=900.0)
    check_workspace("x", tool_down(500.0, 0.0, 100.0, 0.0), p)
    for pose in (tool_down(200.0, 0.0, 100.0, 0.0), tool_down(600.0, 400.0, 100.0, 0.0),
                 tool_down(500.0, 0.0, -1.0, 0.0)):
        with pytest.raises(PickPlaceError, match=r"the grip .* outside the workspace \(radius 300\.\.700 mm"):
            check_workspace("the grip", pose, p)


def test_a_locate_answer_is_read_and_a_bad_one_is_a_clear_error():
    attrs = {"parts": 2, "part.0.x_mm": 1.0, "part.0.y_mm": 2.0, "part.0.z_mm": 3.0, "part.0.yaw_deg": 4.0,
             "part.0.marker": 7, "part.1.x_mm": 5.0, "part.1.y_mm": 6.0, "part.1.z_mm": 7.0, "part.1.yaw_deg": 8.0}
    got = parts_of(attrs)
    assert [(q.x_mm, q.y_mm, q.z_mm, q.yaw_deg, q.marker) for q in got] == [(1.0, 2.0, 3.0, 4.0, 7),
                                                                          (5.0, 6.0, 7.0, 8.0, None)]
    with pytest.raises(PickPlaceError, match="the vision node answered: no markers"):
        parts_of({"error": "no markers"})
    with pytest.raises(PickPlaceError, match="parts = None"):
        parts_of({})
    with pytest.raises(PickPlaceError, match="part 0"):
        parts_of({"parts": 1, "part.0.x_mm": 1.0})


def test_the_part_nearest_the_feeders_centre_inside_it_is_taken():
    feeder = Feeder(400.0, 100.0, 80.0, 80.0)
    far, near, outside = (LocatedPart(430.0, 100.0, 20.0, 0.0), LocatedPart(405.0, 95.0, 20.0, 0.0),
                          LocatedPart(400.0, 300.0, 20.0, 0.0))
    assert on_feeder([outside, far, near], feeder) is near
    assert on_feeder([outside], feeder) is None


def test_the_slots_are_checked_against_the_pallet_and_the_workspace_before_any_motion():
    pallet = Pallet(300.0, -80.0, -90.0, 2, 2, 36.0, 36.0)
    slots = slot_targets(pallet, PickPlaceParams(parts=4), 400.0)
    assert slots[1] == pytest.approx((300.0, -116.0, -90.0))
    with pytest.raises(PickPlaceError, match="5 parts from slot 0 need 5 pallet slots; the pallet has 4"):
        slot_targets(pallet, PickPlaceParams(parts=5), 400.0)
    with pytest.raises(PickPlaceError, match="pallet slot 0 above .* outside the workspace"):
        slot_targets(pallet, PickPlaceParams(parts=1, max_z_mm=420.0), 400.0)


@pytest.mark.parametrize("kw, says", [({"parts": 0}, "parts"), ({"speed": 0}, "speed"),
                                      ({"min_radius_mm": 900.0}, "min_radius_mm"),
                                      ({"min_z_mm": 50.0, "max_z_mm": 10.0}, "min_z_mm = 50")])
def test_a_parameter_outside_its_range_is_refused_naming_it(kw, says):
    with pytest.raises(ValueError, match=says):
        PickPlaceParams(**kw)
