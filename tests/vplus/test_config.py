"""Configuration instructions: LEFTY/RIGHTY, ABOVE/BELOW, FLIP/NOFLIP, SINGLE/MULTIPLE choose the
joint solution of the next motion to a transformation, in the one robot model both backends share
(``Controller.request_config``, ``viper_s850.inverse(config=...)``)."""

from __future__ import annotations

import pytest

from aioadept.robots import viper_s850 as kin
from aioadept.sim.controller import Controller
from aioadept.vplus import Emulator, VPlusError

START = (32.0, -116.0, 196.0, 74.0, 88.0, -108.0)     # RIGHTY ABOVE NOFLIP, high above the table
TARGET = "TRANS({:.6f}, {:.6f}, {:.6f}, {:.6f}, {:.6f}, {:.6f})".format(*kin.forward(START).as_tuple())


def joints_after(words: str, target: str = TARGET, start=START) -> tuple[float, ...]:
    emu = Emulator.from_source(
        f".PROGRAM t()\n\tMOVE #PPOINT({', '.join(map(str, start))})\n\tBREAK\n{words}\n\tMOVE {target}\n\tBREAK\n"
        "\tHERE #j\n.END\n", filename="c.V2", strict=True)
    emu.call("t")
    return emu.globals["#j"].joints_deg


def pose_of(joints) -> tuple[float, ...]:
    return kin.forward(joints).as_tuple()


@pytest.mark.parametrize(("word", "flag", "value"), [
    ("FLIP", "wrist", -1), ("BELOW", "elbow", -1), ("LEFTY", "shoulder", -1)])
def test_the_same_target_in_another_configuration_is_another_joint_solution(word, flag, value):
    plain = joints_after("")
    other = joints_after("\t" + word)
    assert getattr(kin.configuration(plain), flag) == -value
    assert getattr(kin.configuration(other), flag) == value
    assert max(abs(a - b) for a, b in zip(plain, other, strict=True)) > 20.0
    # both are the target
    assert pose_of(other) == pytest.approx(pose_of(plain), abs=1e-6)
    # and the request was for that motion only: the arm stays in it, the next motion keeps it
    again = joints_after(f"\t{word}\n\tMOVE {TARGET}\n\tBREAK\n")
    assert getattr(kin.configuration(again), flag) == value


def test_the_default_words_keep_the_configuration_the_arm_is_in():
    assert joints_after("\tRIGHTY\n\tABOVE\n\tNOFLIP") == pytest.approx(joints_after(""), abs=1e-9)


def test_single_keeps_j6_within_half_a_turn_multiple_takes_the_nearest():
    start = (0.0, -90.0, 180.0, 0.0, 90.0, 300.0)
    here = "TRANS(480, 0, 710, 0, 180, 300)"
    assert joints_after("\tMULTIPLE", here, start)[5] == pytest.approx(300.0, abs=1e-6)
    assert joints_after("\tSINGLE", here, start)[5] == pytest.approx(-60.0, abs=1e-6)


def test_a_straight_line_cannot_change_configuration():
    emu = Emulator.from_source(f".PROGRAM t()\n\tMOVE #PPOINT({', '.join(map(str, START))})\n\tBREAK\n\tFLIP\n"
                               f"\tMOVES {TARGET}\n.END\n", filename="c.V2", strict=True)
    with pytest.raises(VPlusError, match="configuration change"):
        emu.call("t")
    assert emu.controller.joints_at(emu.time_s) == pytest.approx(START)


def test_the_python_sim_model_takes_the_same_request():
    ctl = Controller(joints_deg=START, instant=True)
    pose = kin.forward(joints_after("\tFLIP"))
    ctl.request_config(wrist=-1)
    for _ in ctl.move_pose(pose):
        pass
    assert kin.configuration(ctl.trajectory.end_deg).wrist == -1
    assert ctl.trajectory.end_deg == pytest.approx(joints_after("\tFLIP"), abs=1e-6)
    assert ctl.config_request is None          # consumed by that motion


def test_a_configuration_the_joint_limits_exclude_is_refused_before_anything_moves():
    start = (-30.0, -80.0, 170.0, 10.0, 60.0, 20.0)
    emu = Emulator.from_source(f".PROGRAM t()\n\tMOVE #PPOINT({', '.join(map(str, start))})\n\tBREAK\n\tBELOW\n"
                               "\tMOVE TRANS(380, -220, 420, 30, 150, 10)\n.END\n", filename="c.V2", strict=True)
    with pytest.raises(VPlusError, match="Joint limit"):
        emu.call("t")
    assert emu.controller.joints_at(emu.time_s) == pytest.approx(start)
    assert emu.controller.config_request is None      # the refused motion took the request with it
