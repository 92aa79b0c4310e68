"""The cell file's [world] table: read into a WorldConfig, every value checked with one line naming the file, the
key and what was expected; the JSON table a starter hands to the nodes reads back to the same world."""

from __future__ import annotations

import json

import pytest

from aioadept.apps.cell import write_world_file
from aioadept.cell.config import CellConfig
from aioadept.errors import ConfigError
from aioadept.sim.io import INPUTS
from aioadept.cell.world import INPUT_SIGNALS, load_world, world_from_table, world_to_table

GOOD = {
    "table_z_mm": 5,
    "parts": [{"id": 1, "shape": "box", "size_mm": [40, 30, 20], "colour": "red", "marker": 3, "x_mm": 450},
              {"id": 2, "shape": "cylinder", "size_mm": [30, 25], "colour": [10, 20, 30], "y_mm": -100,
               "marker": 4, "marker_mm": 15}],
    "feeder": {"x_mm": 450, "y_mm": 0, "sensor": 1003},
    "pallet": {"x_mm": 300, "y_mm": 200, "rows": 2, "cols": 2},
    "camera": {"x_mm": 400, "z_mm": 1000, "focal_length_mm": 12},
}


def test_a_good_table_and_its_json_round_trip(tmp_path):
    w = world_from_table(GOOD, "cell.toml [world]")
    assert w.part(2).size_mm == (30.0, 30.0, 25.0) and w.part(2).colour == (10, 20, 30)
    assert w.part(1).marker == 3 and w.feeder.sensor == 1003 and w.pallet.slots == 4
    assert w.camera.focal_length_mm == 12.0 and w.table_z_mm == 5.0
    assert world_from_table(json.loads(json.dumps(world_to_table(w)))) == w
    path = write_world_file(CellConfig(world=w), tmp_path)
    assert load_world(path) == w


def test_the_cell_file_reads_world(tmp_path):
    f = tmp_path / "cell.toml"
    f.write_text('[world]\ntable_z_mm = 1.5\n[[world.parts]]\nid = 9\nshape = "cylinder"\nsize_mm = [20, 10]\n')
    cfg = CellConfig.from_toml(f)
    assert cfg.world is not None and cfg.world.part(9).shape == "cylinder"
    assert load_world(f) == cfg.world
    assert CellConfig().world is None


def bad(**change) -> dict:
    data = json.loads(json.dumps(GOOD))
    for path, value in change.items():
        keys = path.split("__")
        d = data
        for k in keys[:-1]:
            d = d[int(k)] if isinstance(d, list) else d[k]
        d[keys[-1]] = value
    return data


@pytest.mark.parametrize(("data", "message"), [
    (bad(grip_tolerance_mm=0), "w [world]: grip_tolerance_mm = 0.0: expected a number > 0 and <= 50 mm"),
    (bad(parts__0__shape="sphere"), 'w [world] parts[0]: shape = "sphere": expected one of box, cylinder'),
    (bad(parts__0__size_mm=[40, 30]), "w [world] parts[0]: size_mm = [40, 30]: expected [length, width, height]"),
    (bad(parts__1__size_mm=[30, -1]), "w [world] parts[1]: size_mm = [30, -1]: expected [diameter, height]"),
    (bad(parts__0__colour="mauve"), 'w [world] parts[0]: colour = "mauve": expected one of red'),
    (bad(parts__0__colour=[1, 2, 300]), "w [world] parts[0]: colour = [1, 2, 300]: expected [r, g, b]"),
    (bad(parts__0__marker=50), "w [world] parts[0]: marker = 50: expected an id in 0..49"),
    (bad(parts__1__marker_mm=25), "w [world] parts[1]: marker_mm = 25: the marker and its white margin do not fit"),
    (bad(parts__1__id=1), "w [world]: parts: id 1 is used twice"),
    (bad(parts__1__marker=3), "w [world]: parts: marker 3 is used twice"),
    (bad(parts__0__x_mm=1e9), "w [world] parts[0]: x_mm = 1000000000.0: expected a number in -2000..2000 mm"),
    (bad(parts__0__colour_typo=1), "w [world] parts[0]: unknown key(s) colour_typo"),
    (bad(feeder__sensor=12), "w [world] feeder: sensor = 12: expected an integer in 1001..1512"),
    (bad(pallet__rows=0), "w [world] pallet: rows = 0: expected an integer in 1..100"),
    (bad(camera__z_mm=20), "w [world] camera: z_mm = 20: expected the camera above the table"),
    (bad(camera__f_number="8"), 'w [world] camera: f_number = "8": expected a number, got a string'),
    (bad(aruco_dict="DICT_9X9"), 'w [world]: aruco_dict = "DICT_9X9": expected one of DICT_4X4_50'),
    (bad(robots=1), "w [world]: unknown key(s) robots"),
])
def test_each_bad_value_is_one_line_naming_file_and_key(data, message):
    with pytest.raises(ConfigError) as info:
        world_from_table(data, "w [world]")
    text = str(info.value)
    assert text.startswith(message) and "\n" not in text


def test_a_part_needs_an_id():
    data = bad()
    del data["parts"][0]["id"]
    with pytest.raises(ConfigError, match=r"parts\[0\]: id missing"):
        world_from_table(data, "w [world]")


def test_the_sensor_range_is_the_sims_inputs():
    assert (INPUT_SIGNALS.lo, INPUT_SIGNALS.hi) == (INPUTS.start, INPUTS.stop - 1)


def test_a_cell_file_without_world_given_as_world_file(tmp_path):
    f = tmp_path / "cell.toml"
    f.write_text("[robot]\nport = 1\n")
    with pytest.raises(ConfigError, match="no \\[world\\] table"):
        load_world(f)


def test_the_example_world_loads_and_its_camera_sees_every_marker():
    from pathlib import Path

    import cv2

    from aioadept.world import World
    from aioadept.vision.world_camera import WorldView

    example = Path(__file__).resolve().parents[2] / "examples" / "world-cell.toml"
    cfg = CellConfig.from_toml(example)
    w = cfg.world
    assert w is not None and w.feeder is not None and w.pallet is not None and w.camera is not None
    world = World(w)
    assert world.sensor_on(), "a part lies on the feeder"
    image = WorldView(w, seed=0).render(world.snapshot(0.0).parts)
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, w.aruco_dict))
    _, ids, _ = cv2.aruco.ArucoDetector(dictionary).detectMarkers(image)
    assert sorted(ids.ravel().tolist()) == sorted(p.marker for p in w.parts)
    # every pallet slot is in the camera's view too
    uv = WorldView(w).project([(*w.pallet.slot_xy(i)[:2], w.table_z_mm) for i in range(w.pallet.slots)])
    assert ((uv >= 0) & (uv < [w.camera.width_px, w.camera.height_px])).all()
