"""Refuse what V+ refuses, at load or at run as V+ does.

- V+ Language User's Guide v17, p. 111 (Assignment Operator): "Location variables require the use of the SET
  instruction for a valid assignment statement. The instruction: loc_var1 = loc_var2 is unacceptable for location
  and precision-point variables." Refused at load when the value is a location by its form, at run otherwise.
- p. 105 (Arrays): "If a data type different from the one the array was originally created with is specified, an
  error will result." (at run: array typing is dynamic).
- p. 36 (Program Organization): "AUTO, LOCAL, or GLOBAL instructions must precede any executable program
  instructions" (the editor refuses the step: at load).
- p. 35 (Program Lines): "A step label is a programmer-specified integer (0 to 65535)" (at load).
"""

from __future__ import annotations

import pytest

from aioadept.vplus import Emulator, VPlusError


def load(src: str) -> Emulator:
    return Emulator.from_source(src, filename="ref.V2", robot=False)


@pytest.mark.parametrize("line", ["l = TRANS(1,2,3,0,0,0)", "#p = #PPOINT(1,2,3,4,5,6)", "l = TRANS(1,2,3,0,0,0):m",
                                  "a[2] = INVERSE(m)"])
def test_a_location_assigned_without_set_is_refused_at_load(line):
    emu = load(f".PROGRAM p()\n\tSET m = TRANS(0,0,0,0,0,0)\n\t{line}\n.END\n")
    [problem] = emu.problems
    assert (problem.file, problem.line, problem.program) == ("ref.V2", 3, "p")
    assert "SET" in problem.message
    with pytest.raises(VPlusError):
        emu.call("p")


def test_a_location_copied_without_set_is_refused_at_run():
    emu = load(".PROGRAM p()\n\tSET m = TRANS(1,2,3,0,0,0)\n\tn = m\n.END\n")
    assert not emu.problems
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert "SET" in str(info.value) and "n" not in emu.globals


def test_set_still_assigns_locations():
    emu = load(".PROGRAM p()\n\tSET m = TRANS(1,2,3,0,0,0)\n\tSET n = m\n\tSET #q = #PPOINT(1,2,3,4,5,6)\n"
               "\tSET a[1] = n\n.END\n")
    emu.call("p")
    assert emu.globals["a"][1].x == pytest.approx(1)


@pytest.mark.parametrize("first, second", [
    ("a[1] = 5", "SET a[2] = TRANS(1,2,3,0,0,0)"),
    ("SET a[1] = TRANS(1,2,3,0,0,0)", "a[2] = 5"),
    ("SET a[1] = TRANS(1,2,3,0,0,0)", "DECOMPOSE a[2] = TRANS(1,2,3,0,0,0)"),
])
def test_an_array_mixing_reals_and_locations_is_an_error_at_run(first, second):
    emu = load(f".PROGRAM p()\n\t{first}\n\t{second}\n.END\n")
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert info.value.line == 3 and "array a[]" in str(info.value)
    assert len(emu.globals["a"]) == 1


def test_a_location_array_from_the_locations_section_keeps_its_type():
    emu = load(".PROGRAM p()\n\tpick[2] = 1\n.END\n.LOCATIONS\npick[1] 1 2 3 0 0 0\n.END\n")
    with pytest.raises(VPlusError):
        emu.call("p")


@pytest.mark.parametrize("decl", ["AUTO i", "LOCAL j", "GLOBAL k", "AUTO DOUBLE d"])
def test_a_declaration_after_an_executable_instruction_is_refused_at_load(decl):
    emu = load(f".PROGRAM p()\n\t; comment\n\tAUTO a\n\n\tx = 1\n\t{decl}\n.END\n")
    [problem] = emu.problems
    assert (problem.line, problem.program) == (6, "p") and decl.split()[0] in problem.message


def test_declarations_before_the_first_instruction_load():
    emu = load(".PROGRAM p()\n\t; comment\n\tAUTO a\n\n\tLOCAL b\n\tGLOBAL c\n\tx = 1\n.END\n")
    assert not emu.problems


@pytest.mark.parametrize("src, line", [
    ("65536\tx = 1", 2), ("70000 x = 1", 2), ("\tGOTO 65536", 2), ("\tIF x THEN\n\tEND\n\tIF 1 GOTO 99999", 4),
])
def test_labels_outside_0_to_65535_are_refused_at_load(src, line):
    emu = load(f".PROGRAM p()\n{src}\n.END\n")
    assert [p.line for p in emu.problems] == [line] and "65535" in emu.problems[0].message


def test_labels_0_and_65535_load_and_run():
    emu = load(".PROGRAM p()\n\tGOTO 65535\n0\tx = 1\n65535\ty = 2\n.END\n")
    assert not emu.problems
    emu.call("p")
    assert "x" not in emu.globals and emu.globals["y"] == 2.0
