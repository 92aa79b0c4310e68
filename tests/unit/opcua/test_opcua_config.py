"""``aioadept opcua --config CELL`` (aioadept.opcua.config, the command's options): the robots of a cell file, one
MotionDevice each with its model's axes and category and the file's identity; every mistake one line naming the
file and the key."""

from __future__ import annotations

import pytest

from aioadept.cell.schema import ConfigError
from aioadept.opcua.config import plan_from_dict
from aioadept.opcua.mapping import (DEGREE, MILLIMETRE, MILLIMETRE_PER_SECOND, AxisMotionProfile, MotionDeviceCategory,
                                    identity_of_model)

TWO = {"robot": {"host": "10.0.0.5"},
       "robots": [{"name": "arm", "model": "viper-s650", "port": 1301, "state_endpoint": "tcp://10.0.0.5:5561"},
                  {"name": "scara", "model": "cobra-s800", "port": 1302, "state_endpoint": "tcp://10.0.0.6:5561",
                   "host": "10.0.0.6"}],
       "opcua": {"endpoint": "opc.tcp://127.0.0.1:4841", "devices": {"scara": {"serial_number": "C-7",
                                                                                "controller_model": "eMB-40R"}}}}


def test_every_robots_entry_is_a_motion_device_with_its_model_s_axes_and_the_file_s_identity() -> None:
    plan = plan_from_dict(TWO, source="cell.toml")
    arm, scara = plan.robots
    assert plan.many and plan.opcua.endpoint == "opc.tcp://127.0.0.1:4841"
    assert (arm.name, arm.host, arm.port, arm.state_endpoint) == ("arm", "10.0.0.5", 1301, "tcp://10.0.0.5:5561")
    assert (scara.host, scara.port) == ("10.0.0.6", 1302)
    a, s = arm.identity, scara.identity
    assert (a.axes, a.model, a.category) == (6, "Viper s650", MotionDeviceCategory.ARTICULATED_ROBOT)
    assert (s.axes, s.model, s.category) == (4, "Cobra s800", MotionDeviceCategory.SCARA_ROBOT)
    assert (s.serial_number, s.controller_model, a.serial_number) == ("C-7", "eMB-40R", "")
    assert [s.profile(i) for i in range(1, 5)] == [AxisMotionProfile.ROTARY, AxisMotionProfile.ROTARY,
                                                   AxisMotionProfile.LINEAR, AxisMotionProfile.ROTARY]
    assert s.units(3) == (MILLIMETRE, MILLIMETRE_PER_SECOND) and s.units(4)[0] == DEGREE
    assert s.axis_names == ("joint_1", "joint_2", "joint_3", "joint_4")
    assert MILLIMETRE.unit_id == 0x4D4D54 and MILLIMETRE_PER_SECOND.unit_id == 0x433136  # UNECE MMT, C16


def test_one_robot_says_its_model_or_leaves_model_and_category_bad() -> None:
    unsaid = plan_from_dict({"robot": {"port": 1240}}).robots[0]
    assert (unsaid.name, unsaid.identity.axes, unsaid.identity.model, unsaid.identity.category) == \
        ("Robot1", 6, "", None)
    said = plan_from_dict({"robot": {"port": 1240, "model": "cobra-s600"},
                           "opcua": {"name": "Cobra1", "devices": {"Cobra1": {"model": "Cobra s600 (2019)",
                                                                              "category": "OTHER"}}}}).robots[0]
    assert (said.name, said.identity.axes, said.identity.model, said.identity.category) == \
        ("Cobra1", 4, "Cobra s600 (2019)", MotionDeviceCategory.OTHER)
    assert identity_of_model("cobra-s600").linear == (False, False, True, False)


@pytest.mark.parametrize("change, says", [
    ({"opcua": {"devices": {"r9": {}}}}, "cell.toml [opcua.devices.r9]: no robot is called 'r9'"),
    ({"opcua": {"devices": {"arm": {"category": "DELTA"}}}}, "[opcua.devices.arm]: category = 'DELTA': expected one of"),
    ({"opcua": {"devices": {"arm": {"serial": "x"}}}}, "[opcua.devices.arm]: unknown key(s) serial"),
    ({"opcua": {"endpoint": 4840}}, "cell.toml [opcua]: endpoint = 4840: expected a string"),
    ({"opcua": {"stale_after_s": 0}}, "stale_after_s = 0.0: expected seconds > 0"),
    ({"robots": [{"name": "arm", "port": 0}]}, 'cell.toml [[robots]] name = "arm": port 0 picks a free port'),
    ({"robots": [{"name": "arm", "port": 1301}, {"name": "b", "port": 1301}]}, "10.0.0.5:1301 is also robot 'arm'"),
    ({"robots": [{"name": "arm", "model": "puma-560"}]}, "unknown robot model 'puma-560'"),
    ({"bus": {"transport": "zenoh"}}, 'cell.toml [bus]: transport = "zenoh": aioadept opcua follows robot.state over '
                                      'ZeroMQ only'),
])
def test_a_mistake_in_the_cell_file_is_one_line_naming_the_key(change: dict, says: str) -> None:
    data = {**TWO, **change}
    if "robots" in change:
        data.pop("opcua")  # its devices are TWO's robots'
    with pytest.raises(ConfigError) as err:
        plan_from_dict(data, source="cell.toml")
    assert says in str(err.value) and "\n" not in str(err.value)


def test_with_robots_entries_a_robot_option_on_the_command_line_is_refused_in_one_line(tmp_path, capsys) -> None:
    from aioadept.cli.opcua import main

    cell = tmp_path / "cell.toml"
    cell.write_text('[[robots]]\nname = "a"\nport = 1301\nstate_endpoint = "tcp://127.0.0.1:5561"\n')
    assert main(["--config", str(cell), "--robot", "127.0.0.1:1400"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"aioadept opcua: --robot: {cell} has [[robots]]: each robot's entry says its own"]
    # The [opcua] table's endpoint is checked as --endpoint is: beyond loopback it is refused.
    cell.write_text('[opcua]\nendpoint = "opc.tcp://0.0.0.0:4840"\n[robot]\nport = 1301\n')
    assert main(["--config", str(cell)]) == 2
    assert "0.0.0.0 is not loopback" in capsys.readouterr().err


def test_the_command_line_names_the_arm_and_overrides_the_file_s_robot(tmp_path) -> None:
    from aioadept.cli.opcua import build_parser, robot_plans

    parser = build_parser()
    (r,) = robot_plans(parser, parser.parse_args(["--robot-model", "cobra-s600", "--serial-number", "C1"]))
    assert (r.identity.axes, r.identity.model, r.identity.category, r.identity.serial_number) == \
        (4, "Cobra s600", MotionDeviceCategory.SCARA_ROBOT, "C1")
    (r,) = robot_plans(parser, parser.parse_args([]))   # no arm named: six axes, Model and category not known
    assert (r.identity.axes, r.identity.model, r.identity.category) == (6, "", None)
    cell = tmp_path / "cell.toml"
    cell.write_text('[robot]\nmodel = "cobra-s800"\nport = 1301\n[opcua]\nname = "c8"\nsecurity = ["sign"]\n')
    args = parser.parse_args(["--config", str(cell), "--robot-model", "viper-s650", "--robot", "10.1.1.1:1400"])
    (r,) = robot_plans(parser, args)
    assert (r.name, r.host, r.port, r.identity.axes, r.identity.model) == ("c8", "10.1.1.1", 1400, 6, "Viper s650")
    assert args.security == "sign"
