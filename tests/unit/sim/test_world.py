"""The simulated world, pure (no sockets, no clock): grasping within tolerance, following the tool, release onto
the table or a drop with an error event, the feeder sensor; and the world inside the controller (the hand's
valves grasp and release, the closed-fully switch tells a grip from a miss, the sensor drives its input)."""

from __future__ import annotations

import math

import pytest

from aioadept.geometry import Pose, pose_error
from aioadept.sim.controller import Controller
from aioadept.sim.io import DigitalIO, HandConfig
from aioadept.world import Feeder, Pallet, PartSpec
from aioadept.world import World
from aioadept.world import WorldConfig

DOWN = dict(yaw=0.0, pitch=180.0, roll=0.0)  # tool z pointing down


def world(**kw) -> World:
    parts = (PartSpec(1, "box", (40.0, 30.0, 20.0), x_mm=400.0, y_mm=100.0, yaw_deg=30.0),
             PartSpec(2, "cylinder", (30.0, 30.0, 25.0), x_mm=500.0, y_mm=-100.0))
    return World(WorldConfig(table_z_mm=10.0, parts=parts, feeder=Feeder(400.0, 100.0, 80.0, 80.0, 1002), **kw))


def tool(x, y, z, **rot) -> Pose:
    return Pose(x, y, z, **{**DOWN, **rot})


def test_grasp_within_tolerance_only_and_the_part_follows_the_tool():
    w = world()
    assert w.grasp_candidate(tool(400 + 3.5, 100, 20)) is None, "3.5 mm off the axis: outside the 3 mm tolerance"
    assert w.grasp_candidate(tool(400, 100, 35)) is None, "above the part's top: the fingers close over it"
    assert w.grasp_candidate(tool(400, 100, 20, pitch=150.0)) is None, "tool tilted 30 deg"
    events = w.hand_closed(1.0, tool(402, 100, 20))
    assert [e.kind for e in events] == ["grasped", "sensor"] and events[0].part == 1
    assert w.held == 1 and events[1].signal == 1002 and events[1].on is False, "the part left the feeder"
    before = w.snapshot(1.0, tool(402, 100, 20)).part(1)
    moved = w.snapshot(2.0, tool(452, 80, 120, yaw=40.0)).part(1)
    assert moved.grasped and math.isclose(moved.pose.z - before.pose.z, 100.0, abs_tol=1e-9)
    assert math.isclose(moved.heading_deg - before.heading_deg, 40.0, abs_tol=1e-9), "it turns with the tool"
    # the grip offset (2 mm) is kept: no centring
    assert math.isclose(math.hypot(moved.pose.x - 452, moved.pose.y - 80), 2.0, abs_tol=1e-9)


def test_release_on_the_table_snaps_to_the_plane_keeping_x_y_and_heading():
    w = world()
    w.hand_closed(0.0, tool(500, -100, 22))         # the cylinder, fingers 12 mm above its bottom (z 10)
    events = w.hand_opened(1.0, tool(600, 50, 24.5, yaw=15.0))   # its bottom 2.5 mm above the table: within 3
    assert [e.kind for e in events] == ["released"]
    p = w.snapshot(1.0).part(2)
    assert not p.grasped and not p.dropped
    assert (round(p.pose.x, 9), round(p.pose.y, 9), round(p.pose.z, 9)) == (600.0, 50.0, 10.0)
    assert math.isclose(p.heading_deg, 15.0, abs_tol=1e-9)


def test_a_drop_from_higher_up_is_an_error_event_and_the_part_lies_below():
    w = world()
    w.hand_closed(0.0, tool(400, 100, 20))
    events = w.hand_opened(2.0, tool(300, 0, 60))    # bottom 40 mm above the table
    assert [e.kind for e in events] == ["dropped"] and events[0].error
    assert "40.0 mm above the table" in events[0].text
    p = w.snapshot(2.0).part(1)
    assert p.dropped and (round(p.pose.x, 6), round(p.pose.y, 6), round(p.pose.z, 6)) == (300.0, 0.0, 10.0)
    assert [e.kind for e in w.events_since(0)[0]] == ["sensor", "grasped", "sensor", "dropped"]
    # picking it up again clears the mark
    w.hand_closed(3.0, tool(300, 0, 15))
    assert w.snapshot(3.0, tool(300, 0, 15)).part(1).dropped is False


def test_the_feeder_sensor_follows_parts_in_its_rectangle():
    w = world()
    assert w.sensor_on() and w.snapshot(0.0).sensors_on == (1002,)
    w.hand_closed(0.0, tool(400, 100, 20))
    assert not w.sensor_on()
    w.hand_opened(1.0, tool(430, 130, 10))           # back inside the 80 x 80 rectangle (edge at 440, 140)
    assert w.sensor_on()
    w.hand_closed(2.0, tool(430, 130, 12))
    w.hand_opened(3.0, tool(450, 130, 10))           # x 450: outside
    assert not w.sensor_on() and w.snapshot(3.0).sensors_on == ()


def test_the_nearest_part_is_grasped_and_closing_again_changes_nothing():
    parts = (PartSpec(1, "cylinder", (20, 20, 20), x_mm=0.0), PartSpec(2, "cylinder", (20, 20, 20), x_mm=4.0))
    w = World(WorldConfig(parts=parts, grip_tolerance_mm=5.0))
    assert w.grasp_candidate(tool(3.0, 0, 5)) == 2
    w.hand_closed(0.0, tool(3.0, 0, 5))
    assert w.hand_closed(0.5, tool(0.0, 0, 5)) == [] and w.held == 2
    assert w.hand_opened(1.0, tool(0, 0, 50))[0].kind == "dropped"
    assert w.hand_opened(1.5, tool(0, 0, 50)) == [], "nothing held: nothing released"


def test_duplicate_part_ids_are_refused():
    with pytest.raises(ValueError, match="unique"):
        World(WorldConfig(parts=(PartSpec(1), PartSpec(1))))


def test_pallet_slots_row_by_row_turned_with_the_pallet():
    p = Pallet(100.0, 200.0, yaw_deg=90.0, rows=2, cols=3, pitch_x_mm=50.0, pitch_y_mm=40.0)
    assert p.slots == 6
    x, y, h = p.slot_xy(4)                           # row 1, col 1: 50 along the pallet's x, 40 along its y
    assert (round(x, 9), round(y, 9), h) == (60.0, 250.0, 90.0)
    with pytest.raises(IndexError):
        p.slot_xy(6)


# -- the world inside the controller: the hand's valves move the parts -----------------------------------------
def controller_with_world(part_xy=(0.0, 0.0)) -> Controller:
    probe = Controller(instant=True)
    here = probe.here                                  # home pose: tool pointing down?
    assert here.pitch == pytest.approx(180.0, abs=1e-6) or abs(abs(here.pitch) - 180.0) < 1e-6
    spec = PartSpec(7, "cylinder", (30.0, 30.0, 40.0), x_mm=here.x + part_xy[0], y_mm=here.y + part_xy[1])
    cfg = WorldConfig(table_z_mm=here.z - 20.0, parts=(spec,),
                      feeder=Feeder(here.x, here.y, 100.0, 100.0, 1003))
    return Controller(instant=True, io=DigitalIO(HandConfig(close_time_s=0.04)), world=World(cfg))


def test_the_controller_grasps_on_close_and_the_switch_says_so():
    ctl = controller_with_world()
    assert ctl.io.state(1003), "the feeder sensor drives its input from the start"
    ctl.io.hand_now("close", 0.0)
    assert ctl.world.held == 7 and ctl.io.hand.part
    assert not ctl.io.sig([1001], 1.0), "closed on a part: the closed-fully switch stays off"
    assert not ctl.io.state(1003), "the part left the feeder"
    snap = ctl.world_snapshot(1.0)
    assert snap.part(7).grasped
    ctl.io.hand_now("open", 2.0)
    assert ctl.world.held is None and not ctl.io.hand.part and ctl.io.state(1003)


def test_the_controller_closes_on_nothing_when_the_part_is_off_by_more_than_the_tolerance():
    ctl = controller_with_world(part_xy=(5.0, 0.0))
    ctl.io.hand_now("close", 0.0)
    assert ctl.world.held is None
    assert ctl.io.sig([1001], 1.0), "closed on nothing: the switch is on"


def test_a_part_follows_the_planned_motion_of_the_tool():
    ctl = controller_with_world()
    ctl.io.hand_now("close", 0.0)
    start = ctl.world_snapshot(0.0).part(7).pose
    target = ctl.here @ Pose(z=-50.0)                   # 50 mm up (tool z points down)
    gen = ctl.move_pose(target)
    for _ in gen:
        pass
    t_end = ctl.trajectory.t_rest_s
    end = ctl.world_snapshot(t_end + 1.0).part(7).pose
    dist, angle = pose_error(start @ Pose(z=50.0), end)
    assert dist < 1e-6 and angle < 1e-6


def test_the_feeder_sensor_may_not_be_the_hands_switch():
    from aioadept.sim.server import SimOptions

    cfg = WorldConfig(parts=(PartSpec(1),), feeder=Feeder(0.0, 0.0, sensor=1001))
    with pytest.raises(ValueError, match="feeder sensor 1001 is the hand's closed-fully switch"):
        SimOptions(world=cfg)
    assert SimOptions(world=cfg, hand=HandConfig(closed_switch=1005)).make_controller().world is not None
