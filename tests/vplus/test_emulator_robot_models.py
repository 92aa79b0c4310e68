"""The V+ emulator on a Cobra: V+ programs move the SCARA with its own kinematics (``Controller(model=...)``, the one
robot model both backends share): HERE reports yaw 0, pitch 180 and the quill in roll, precision points have four
joints, LEFTY/RIGHTY choose J2's sign, a location that asks another pitch is refused (INRANGE says so, MOVE raises
*Location out of range*) before anything moves."""

from __future__ import annotations

import pytest

from aioadept.robots import model
from aioadept.sim.controller import Controller
from aioadept.vplus import Emulator, VPlusError
from aioadept.vplus.emulator import make_robot

COBRAS = ["cobra-s600", "cobra-s800"]


def emulator(name: str, body: str) -> Emulator:
    ctl = Controller(model=model(name), time_scale=20.0)
    return Emulator.from_source(f".PROGRAM t()\n{body}\n.END\n", filename="c.V2", strict=True,
                                robot=make_robot(ctl))


def trans(pose) -> str:
    return "TRANS({:.6f}, {:.6f}, {:.6f}, {:.6f}, {:.6f}, {:.6f})".format(*pose.as_tuple())


@pytest.mark.parametrize("name", COBRAS)
def test_a_v_plus_program_moves_a_cobra_to_a_location_and_back_to_a_precision_point(name):
    m = model(name)
    goal = (20.0, 70.0, 150.0, 40.0)
    emu = emulator(name, f"\tHERE h0\n\tMOVE {trans(m.forward(goal))}\n\tBREAK\n\tHERE h1\n\tHERE #j1\n"
                         f"\tMOVES {trans(m.forward(m.home_deg))}\n\tBREAK\n\tHERE #j2\n"
                         "\tMOVE #PPOINT(0, 90, 100, 0)\n\tBREAK\n\tHERE #j3\n")
    emu.call("t")
    g = emu.globals
    assert g["h0"].to_pose().as_tuple() == pytest.approx(m.forward(m.home_deg).as_tuple(), abs=1e-6)
    h1 = g["h1"].to_pose()
    assert (h1.yaw, h1.pitch) == (0.0, 180.0)
    assert h1.as_tuple() == pytest.approx(m.forward(goal).as_tuple(), abs=1e-6)
    assert g["#j1"].joints_deg == pytest.approx(goal, abs=1e-6)
    assert g["#j2"].joints_deg == pytest.approx(m.home_deg, abs=1e-6)
    assert g["#j3"].joints_deg == pytest.approx((0.0, 90.0, 100.0, 0.0), abs=1e-6)


@pytest.mark.parametrize("name", COBRAS)
def test_lefty_takes_the_other_elbow_to_the_same_location(name):
    m = model(name)
    goal = m.forward((10.0, 60.0, 80.0, 0.0))
    emu = emulator(name, f"\tLEFTY\n\tMOVE {trans(goal)}\n\tBREAK\n\tHERE #j\n")
    emu.call("t")
    j = emu.globals["#j"].joints_deg
    assert j[1] < 0 and m.forward(j).as_tuple() == pytest.approx(goal.as_tuple(), abs=1e-6)


@pytest.mark.parametrize("name", COBRAS)
def test_a_location_with_another_pitch_is_refused_before_anything_moves(name):
    m = model(name)
    here = m.forward(m.home_deg)
    tilted = "TRANS({:.3f}, {:.3f}, {:.3f}, 0, 170, 0)".format(here.x, here.y, here.z)
    emu = emulator(name, f"\tr = INRANGE({tilted})\n\tf = INRANGE(TRANS(2000, 0, 300, 0, 180, 0))\n"
                         f"\tok = INRANGE({trans(here)})\n\tMOVE {tilted}\n")
    with pytest.raises(VPlusError, match="Location out of range"):
        emu.call("t")
    g = emu.globals
    assert g["ok"] == 0 and g["r"] != 0 and g["f"] != 0
    assert emu.controller.joints_at(emu.time_s) == pytest.approx(m.home_deg)


def test_a_precision_point_with_joints_the_cobra_does_not_have_is_refused():
    emu = emulator("cobra-s600", "\tMOVE #PPOINT(0, 90, 100, 0, 10, 0)\n")
    with pytest.raises(VPlusError, match="4 joints"):
        emu.call("t")
    assert emu.controller.joints_at(emu.time_s) == pytest.approx(model("cobra-s600").home_deg)
