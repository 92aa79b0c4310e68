"""Instruction forms vendor V+ code uses: ACCEL with a profile, SELECT ROBOT, the PARAMETER
and SELECT functions, CALIBRATE, a radix constant after a word operator, a CALL of a program not loaded. A form the
emulator lacks says "not implemented", never "unexpected"."""

from __future__ import annotations

import pytest

from aioadept.vplus import Emulator, VPlusError
from aioadept.vplus.parse import parse_statement
from aioadept.vplus.unparse import unparse


def emu_of(body: str, **kw) -> Emulator:
    return Emulator.from_source(".PROGRAM t()\n" + body + "\n.END\n", filename="v.V2", strict=True, **kw)


def test_accel_with_a_profile_sets_the_acceleration_not_the_profile():
    emu = emu_of("\tACCEL (2) 40, 30")
    emu.call("t")
    assert emu.controller.accel_pct == 40.0
    emu = emu_of("\tACCEL (60), 30")          # a parenthesised acceleration stays one
    emu.call("t")
    assert emu.controller.accel_pct == 60.0
    assert unparse(parse_statement("ACCEL (2) 40, 30 ALWAYS")) == "ACCEL (2) 40, 30 ALWAYS"


def test_select_robot_1_is_the_arm_and_another_robot_is_an_error():
    emu = emu_of("\tSELECT ROBOT = 1\n\tr = SELECT(ROBOT)")
    emu.call("t")
    assert emu.globals["r"] == 1.0
    with pytest.raises(VPlusError, match=r"SELECT ROBOT = 2: the emulator has one robot"):
        emu_of("\tSELECT ROBOT = 2").call("t")
    bad = Emulator.from_source(".PROGRAM t()\n\tSELECT VISION = 1\n.END\n", filename="v.V2", robot=False)
    assert [p.message for p in bad.problems] == ["SELECT VISION is not implemented by the emulator (it has SELECT ROBOT)"]


def test_the_parameter_function_reads_what_the_instruction_set():
    emu = emu_of("\tPARAMETER HAND.TIME = 0.25\n\th = PARAMETER(HAND.TIME)\n\tn = PARAMETER(NOT.CALIBRATED)")
    emu.call("t")
    assert emu.globals["h"] == pytest.approx(0.25) and emu.globals["n"] == 0.0
    bad = Emulator.from_source(".PROGRAM t()\n\tx = PARAMETER(BELT.MODE)\n.END\n", filename="v.V2", robot=False)
    assert [p.message for p in bad.problems] == \
        ["PARAMETER(BELT.MODE) is not implemented by the emulator (it has HAND.TIME, NOT.CALIBRATED)"]


def test_calibrate_waits_for_the_arm_at_rest_and_moves_nothing():
    emu = emu_of("\tSET p = HERE\n\tMOVE SHIFT(p BY 0, 0, -40)\n\tCALIBRATE 0, st\n\tt = TIMER(-3)\n"
                 "\tSET q = HERE\n\tCALIBRATE\n\tSET r = HERE\n\td = DISTANCE(q, r)")
    emu.call("t")
    g = emu.globals
    assert g["st"] == 1.0 and g["d"] == 0.0
    assert not emu.robot.in_motion and g["t"] > 0.1         # it waited for the motion to end


def test_a_radix_constant_right_after_a_word_operator():
    emu = emu_of("\tx = ^B1001001 BAND ^B1110011\n\ty = ^H0F BOR ^H30\n\tz = 2 MOD ^B11", robot=False)
    emu.call("t")
    assert (emu.globals["x"], emu.globals["y"], emu.globals["z"]) == (0b1000001, 0x3F, 2.0)


def test_a_call_of_a_program_not_loaded_is_vplus_undefined_program_or_variable_name():
    emu = Emulator.from_source(".PROGRAM t()\n\tCALL nothere()\n.END\n", filename="v.V2", robot=False)
    with pytest.raises(VPlusError) as info:
        emu.call("t")
    assert info.value.message.startswith("*Undefined program or variable name* nothere")



def test_speed_in_mm_per_second_is_named_not_implemented_not_unexpected():
    bad = Emulator.from_source(".PROGRAM t()\n\tSPEED 50 MMPS ALWAYS\n.END\n", filename="v.V2", robot=False)
    assert [(p.column, p.message) for p in bad.problems] == \
        [(11, "SPEED ... MMPS is not implemented by the emulator (its speeds are percent of the maximum)")]
