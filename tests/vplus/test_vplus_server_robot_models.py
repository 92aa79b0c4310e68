"""The shipped V+ server's joint skills on each arm, on the emulator without TCP: rs.init finds how many joints the
arm has (``rs.njnt``, from ``HERE`` as a precision point), ``rs.jcheck`` refuses a value for a joint the arm does not
have and asks the controller's own limits (``INRANGE`` of the precision point), and the state stream's line
carries the arm's joints and zeros after them. The same programs run unchanged on a Viper and on a Cobra."""

from __future__ import annotations

from pathlib import Path

import pytest

from aioadept.robots import model
from aioadept.sim.controller import Controller
from aioadept.vplus import Emulator
from aioadept.vplus.emulator import make_robot

ROOT = Path(__file__).resolve().parents[2] / "vplus"
SERVER = [ROOT / f for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2", "rsstate.V2")]
OK, ILLEGAL, JLIMIT = 0, -410, -1003


def server_on(name: str) -> Emulator:
    emu = Emulator.load(*SERVER, strict=True, robot=make_robot(Controller(model=model(name), time_scale=20.0)))
    emu.call("rs.init")
    return emu


def jcheck(emu: Emulator, q) -> tuple[int, str]:
    emu.globals["rs.xcode"] = 0
    emu.call("rs.jcheck", list(q))
    return emu.globals["rs.xcode"], emu.globals["$rs.xmsg"] if emu.globals["rs.xcode"] else ""


@pytest.mark.parametrize("name,joints", [("viper-s850", 6), ("viper-s650", 6), ("cobra-s600", 4), ("cobra-s800", 4)])
def test_the_server_counts_the_arms_joints(name, joints):
    assert server_on(name).globals["rs.njnt"] == joints


def test_each_arm_is_checked_against_its_own_limits():
    m = model("cobra-s600")
    emu = server_on(m.name)
    home = list(m.home_deg) + [0.0, 0.0]
    assert jcheck(emu, home) == (OK, "")  # J2 at 90 deg: past the Viper's 45, inside the Cobra's 150
    assert emu.globals["#rs.jtgt"].joints_deg == pytest.approx(m.home_deg)
    code, msg = jcheck(emu, home[:4] + [5.0, 0.0])
    assert (code, "4 joints" in msg) == (ILLEGAL, True)
    assert jcheck(emu, [0.0, 90.0, m.limits.max_deg[2] + 1.0, 0.0, 0.0, 0.0])[0] == JLIMIT  # the quill, mm
    assert jcheck(emu, [m.limits.max_deg[0] + 1.0, 90.0, 100.0, 0.0, 0.0, 0.0])[0] == JLIMIT

    viper = server_on("viper-s850")  # the same programs on a six-axis arm
    assert jcheck(viper, [0.0, -90.0, 180.0, 0.0, 90.0, 360.0]) == (OK, "")
    assert viper.globals["#rs.jtgt"].joints_deg == pytest.approx((0.0, -90.0, 180.0, 0.0, 90.0, 360.0))
    assert jcheck(viper, [0.0, -90.0, 180.0, 0.0, 90.0, 361.0])[0] == JLIMIT
    assert jcheck(viper, [0.0, 46.0, 180.0, 0.0, 90.0, 0.0])[0] == JLIMIT


def test_the_state_line_of_a_cobra_has_its_four_joints_and_two_zeros():
    m = model("cobra-s600")
    emu = server_on(m.name)
    a = emu.call("rs.stline", "", "", "").args[0]
    joints = [float(v) for v in a.split(" j=")[1].split(",")]
    assert joints == pytest.approx(list(m.home_deg) + [0.0, 0.0], abs=1e-3)
