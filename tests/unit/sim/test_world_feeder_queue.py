"""The feeder's queue: parts fed one after another, pure and time-driven, from
the cell file's [world.feeder] table; in the controller, both backends' I/O sees the arrival on the sensor input."""

from __future__ import annotations

import math

import pytest

from aioadept.errors import ConfigError
from aioadept.geometry import Pose
from aioadept.sim.controller import Controller
from aioadept.world import World
from aioadept.cell.world import world_from_table, world_to_table

TABLE = {
    "parts": [{"id": 7, "size_mm": [40, 30, 20], "marker": 3, "marker_mm": 15, "x_mm": 400.0, "y_mm": 100.0,
               "yaw_deg": 10.0}],
    "feeder": {"x_mm": 400.0, "y_mm": 100.0, "queue": 3, "interval_s": 0.5, "jitter_mm": 5.0, "jitter_deg": 20.0,
               "seed": 4},
}
DOWN = dict(yaw=0.0, pitch=180.0, roll=0.0)


def test_the_queue_copies_the_template_with_seeded_jitter_inside_the_feeder_and_round_trips():
    w = world_from_table(TABLE)
    fed = [p for p in w.parts if p.fed]
    assert [(p.id, p.fed) for p in fed] == [(8, 1), (9, 2), (10, 3)]
    assert [p.marker for p in fed] == [4, 5, 6], "each its own marker, after the template's"
    for p in fed:
        assert (p.shape, p.size_mm) == ("box", (40.0, 30.0, 20.0))
        assert abs(p.x_mm - 400.0) <= 5.0 and abs(p.y_mm - 100.0) <= 5.0 and abs(p.yaw_deg - 10.0) <= 20.0
    assert len({(p.x_mm, p.y_mm, p.yaw_deg) for p in fed}) == 3, "jittered, not all alike"
    assert world_from_table(TABLE) == w, "the same seed feeds the same parts"
    assert world_from_table(world_to_table(w)) == w
    other = world_from_table({**TABLE, "feeder": {**TABLE["feeder"], "seed": 5}})
    assert [p.x_mm for p in other.parts if p.fed] != [p.x_mm for p in fed]


def test_fed_markers_skip_the_listed_parts_ids_and_repeat_only_when_the_dictionary_runs_out():
    table = {"parts": [{**TABLE["parts"][0], "marker": 48},
                       {"id": 9, "size_mm": [40, 30, 20], "marker": 0, "marker_mm": 15, "x_mm": 0.0}],
             "feeder": {**TABLE["feeder"], "queue": 4}}
    fed = [p.marker for p in world_from_table(table).parts if p.fed]
    assert fed == [49, 1, 2, 3], "DICT_4X4_50: after 48 comes 49, then 0 is part 9's"
    big = world_from_table({**TABLE, "aruco_dict": "DICT_4X4_250", "feeder": {**TABLE["feeder"], "queue": 200}})
    markers = [p.marker for p in big.parts]
    assert len(set(markers)) == len(markers) == 201


@pytest.mark.parametrize("feeder, says", [
    ({"queue": 2, "template": 99}, "template = 99: no part has that id"),
    ({"queue": 2, "jitter_mm": 50.0}, "jitter_mm = 50: a fed part could lie outside the feeder"),
    ({"queue": -1}, "queue"),
    ({"interval_s": -0.1}, "interval_s"),
])
def test_a_bad_queue_is_one_line_naming_the_key(feeder, says):
    with pytest.raises(ConfigError) as info:
        world_from_table({**TABLE, "feeder": {"x_mm": 400.0, "y_mm": 100.0, **feeder}})
    assert says in str(info.value) and "\n" not in str(info.value)


def test_a_queued_part_arrives_interval_after_the_feeder_emptied_and_not_before():
    w = World(world_from_table(TABLE))
    ids = [p.id for p in w.snapshot(0.0).parts]
    assert ids == [7] and w.queued == 3 and w.sensor_on(), "queued parts are not in the world yet"
    grip = Pose(400.0, 100.0, 10.0, **DOWN)
    w.hand_closed(1.0, grip)
    assert w.held == 7 and not w.sensor_on()
    assert w.step(1.2, grip) == [], "the held part still lies over the feeder"
    away = Pose(300.0, -100.0, 100.0, **DOWN)
    assert w.step(2.0, away) == [] and w.next_feed_s() == pytest.approx(2.5)
    assert w.step(2.49, away) == []
    events = w.step(2.5, away)
    assert [e.kind for e in events] == ["fed", "sensor"] and events[0].part == 8 and events[1].on
    assert [p.id for p in w.snapshot(2.5, away).parts] == [7, 8] and w.queued == 2
    assert w.step(2.0, away) == [], "time never runs back"


def test_an_empty_feeder_gets_its_first_part_at_once_and_the_time_scale_shortens_the_interval():
    table = {**TABLE, "parts": [{**TABLE["parts"][0], "x_mm": 200.0}]}  # the template lies elsewhere
    w = World(world_from_table(table), time_scale=5.0)
    assert w.sensor_on() and w.queued == 2 and [p.id for p in w.snapshot(0.0).parts] == [7, 8]
    w.hand_closed(1.0, Pose(*_xy(w, 8), 10.0, **DOWN))
    away = Pose(300.0, -100.0, 100.0, **DOWN)
    w.step(1.0, away)
    assert w.step(1.09, away) == [] and [e.kind for e in w.step(1.1, away)] == ["fed", "sensor"]


def _xy(w: World, part: int) -> tuple[float, float]:
    st = w.snapshot(0.0).part(part)
    return st.pose.x, st.pose.y


def test_in_the_controller_the_arrival_turns_the_sensor_input_on_when_the_io_advances():
    world = World(world_from_table(TABLE))
    ctl = Controller(world=world, instant=True)
    assert ctl.io.sig([1002], 0.0)
    world.hand_closed(0.5, Pose(400.0, 100.0, 10.0, **DOWN))  # as the hand would (the arm is elsewhere)
    ctl.io.set_input(1002, False, 0.5)
    ctl.io.advance(0.6)  # the arm (at home, far from the feeder) carries the part away
    assert not ctl.io.sig([1002], 0.7)
    assert ctl.io.sig([1002], 1.2) and world.queued == 2
    assert math.isclose(max(c.t_s for c in ctl.io.changes if c.signal == 1002), 1.2)
