"""The cell file of several robots: ``[[robots]]``/``[[cameras]]`` become one single-robot cell
per robot, the shared tables are every entry's defaults, each mistake is one line naming the file, the entry and the
key; and the Zenoh keys and node names each robot gets."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from aioadept.cell.config import CellConfig
from aioadept.apps.multicell import prepared
from aioadept.cell.multi import MAX_ROBOTS, is_multi, multi_from_dict
from aioadept.errors import ConfigError

pytestmark = pytest.mark.timeout(20)

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"
R = [{"name": "r1"}, {"name": "r2"}]
C = [{"name": "c1", "robot": "r1"}, {"name": "c2", "robot": "r2"}]


def test_the_example_holds_four_robots_each_with_its_own_camera_and_focal_plane():
    data = tomllib.loads((EXAMPLES / "multi-cell.toml").read_text())
    assert is_multi(data)
    multi = multi_from_dict(data, source="multi-cell.toml")
    assert [(m.robot, m.camera) for m in multi.members] == [("r1", "cam1"), ("r2", "cam2"), ("r3", "cam3"),
                                                            ("r4", "cam4")]
    assert [m.cfg.vision.focus_offset_mm for m in multi.members] == [16.0, 18.0, 20.0, 22.0]
    assert {m.cfg.bus.transport for m in multi.members} == {"zenoh"}


def test_a_single_robot_file_is_not_a_multi_cell_and_still_reads_as_before():
    data = tomllib.loads((EXAMPLES / "cell.toml").read_text())
    assert not is_multi(data)
    assert CellConfig.from_dict(data).robot.port == 1234
    with pytest.raises(ConfigError, match=r"only `aioadept demo --config FILE` runs"):  # focus, experiment
        CellConfig.from_dict({"robots": R, "cameras": C})


def test_shared_tables_are_defaults_an_entry_overrides_and_addresses_not_written_are_free_ports():
    multi = multi_from_dict({"robot": {"time_scale": 4.0, "monitor_speed": 50}, "vision": {"fps": 20.0},
                             "focus": {"delta_z_mm": 1.5},
                             "robots": [{"name": "r1", "monitor_speed": 80}, {"name": "r2", "port": 2100}],
                             "cameras": [{"name": "c1", "robot": "r1", "focus_offset_mm": 12.0},
                                         {"name": "c2", "robot": "r2"}]})
    a, b = (m.cfg for m in multi.members)
    assert (a.robot.time_scale, a.robot.monitor_speed, b.robot.monitor_speed) == (4.0, 80, 50)
    assert (a.vision.fps, a.vision.focus_offset_mm, b.vision.focus_offset_mm) == (20.0, 12.0,
                                                                                   CellConfig().vision.focus_offset_mm)
    assert a.focus.delta_z_mm == b.focus.delta_z_mm == 1.5
    assert (a.robot.port, b.robot.port) == (0, 2100)
    assert a.robot.state_endpoint == a.vision.request_endpoint == a.vision.response_endpoint == "tcp://127.0.0.1:0"


def test_on_zenoh_each_robot_and_camera_gets_its_own_keys_one_router_and_a_node_name():
    multi = multi_from_dict({"bus": {"transport": "zenoh", "cell": "lab", "zenoh_router": "tcp/127.0.0.1:0"},
                             "robots": R, "cameras": C})
    a, b = prepared(multi)
    assert a.cfg.bus.zenoh_router == b.cfg.bus.zenoh_router != "tcp/127.0.0.1:0"  # one free port, picked once
    assert (a.cfg.robot.state_endpoint, a.cfg.vision.request_endpoint, b.cfg.vision.response_endpoint) == (
        "zenoh:aioadept/lab/r1/state", "zenoh:aioadept/lab/c1/request", "zenoh:aioadept/lab/c2/response")
    assert a.cfg.robot.sim_args[-2:] == ["--node", "r1"] and b.cfg.vision.vision_args[-2:] == ["--node", "c2"]
    z = prepared(multi_from_dict({"robots": R, "cameras": C}))  # ZeroMQ: nothing added
    assert z[0].cfg.robot.sim_args == [] and z[0].cfg.robot.state_endpoint == "tcp://127.0.0.1:0"


@pytest.mark.parametrize("data, message", [
    ({"robots": R, "cameras": C[:1]}, "m.toml: robot 'r2' has no camera"),
    ({"robots": R, "cameras": [*C, {"name": "c3", "robot": "r9"}]}, 'm.toml [[cameras]] name = "c3": robot = \'r9\''),
    ({"robots": R, "cameras": [*C, {"name": "c3", "robot": "r1"}]}, "already has camera 'c1'"),
    ({"robots": [{"name": "r1"}, {"name": "r1"}], "cameras": C}, "m.toml [[robots]] #2: name = 'r1': already used"),
    ({"robots": R, "cameras": [{"name": "r2", "robot": "r1"}, C[1]]}, "[[cameras]] #1: name = 'r2': already used"),
    ({"robots": [{"name": "sim"}], "cameras": C}, "name = 'sim': reserved"),
    ({"robots": [{"name": "a/b"}], "cameras": C}, "[[robots]] #1: name = 'a/b': expected"),
    ({"robots": [{"port": 1}], "cameras": C}, "[[robots]] #1: name = None"),
    ({"robots": [{"name": "r1", "port": 70000}, R[1]], "cameras": C}, 'name = "r1": port = 70000: expected an integer'),
    ({"robots": [{"name": "r1", "time_scale": 0}, R[1]], "cameras": C}, 'name = "r1": time_scale = 0'),
    ({"robots": [{"name": "r1", "prot": 1}, R[1]], "cameras": C}, 'name = "r1": unknown key(s) prot'),
    ({"robots": R, "cameras": [{"name": "c1", "robot": "r1", "fps": -1}, C[1]]}, 'name = "c1": fps = -1'),
    ({"robots": R, "cameras": [{"name": "c1", "robot": "r1", "focus_offset_mm": "x"}, C[1]]},
     'name = "c1": focus_offset_mm = "x": expected a number'),
    ({"robots": [{"name": f"r{i}"} for i in range(MAX_ROBOTS + 1)], "cameras": C}, "17 [[robots]]: expected"),
    ({"robots": [], "cameras": []}, "0 [[robots]]: expected an integer in 1..16"),
    ({"robots": {"name": "r1"}, "cameras": C}, "robots: expected an array of tables"),
    ({"cameras": C}, "[[robots]] missing"),
    ({"robots": [{"name": "r1", "port": 2000}, {"name": "r2", "port": 2000}], "cameras": C},
     "robot port '127.0.0.1:2000' of robot 'r2' is also used by robot 'r1'"),
    ({"robot": {"port": 2000}, "robots": R, "cameras": C}, "robot port '127.0.0.1:2000'"),
    ({"robot": {"port": -1}, "robots": R, "cameras": C}, "m.toml [robot]: port = -1"),
    ({"bus": {"transport": "zenoh", "cell": "a/b"}, "robots": R, "cameras": C}, "m.toml [bus]: cell"),
])
def test_every_mistake_is_one_line_naming_the_file_the_entry_and_the_key(data, message):
    with pytest.raises(ConfigError) as info:
        multi_from_dict(data, source="m.toml")
    text = str(info.value)
    assert message in text and "\n" not in text and text.startswith("m.toml")
