"""Words real V+ programs use: NULL, BMASK, DURATION, MOVET, radix constants, a comment after
the .PROGRAM line, SHIFT with omitted components, BITS and $TRUNCATE as the V+ manuals define them."""

from __future__ import annotations

import pytest

from aioadept.vplus import Emulator, VPlusError


def emu_of(src: str, **kw) -> Emulator:
    return Emulator.from_source(src, filename="w.V2", strict=True, **kw)


def run(body: str, **kw) -> Emulator:
    emu = emu_of(".PROGRAM t()\n" + body + "\n.END\n", **kw)
    emu.call("t")
    return emu


def test_radix_constants_hex_binary_octal_and_power_after_an_operand():
    g = run("\tx = ^H23FF\n\ty = ^B1001\n\tz = ^346\n\tw = 2^3\n\ta[1] = 3\n\tv = a[1]^2\n\tu = (1+1)^4",
            robot=False).globals
    assert (g["x"], g["y"], g["z"], g["w"], g["v"], g["u"]) == (0x23FF, 9.0, 0o346, 8.0, 9.0, 16.0)


def test_a_binary_constant_has_at_most_8_bits_and_d_is_a_double_integer():
    g = run("\tGLOBAL DOUBLE dd\n\tdd = ^D20000001\n\tb = ^B11111111", robot=False).globals
    assert g["b"] == 255.0 and g["dd"] == 20000001.0      # a REAL would hold 20000000
    emu = Emulator.from_source(".PROGRAM t()\n\tx = ^B111111111\n.END\n", filename="w.V2", robot=False)
    assert [(p.line, p.word) for p in emu.problems] == [(2, "^B111111111")]


def test_a_comment_after_the_program_line_may_hold_parentheses():
    emu = emu_of(".PROGRAM p(a, b) ; pick (fast) and place\n\ta = b+1\n.END\n", robot=False)
    assert emu.call("p", 0, 4).args == (5.0, 4.0)


def test_bmask_sets_bits_numbered_from_1():
    g = run("\tm = BMASK(1, 5)\n\tn = BMASK(32)\n\tk = BMASK(3)", robot=False).globals
    assert (g["m"], g["n"], g["k"]) == (17.0, float(2 ** 31), 4.0)
    with pytest.raises(VPlusError, match="BMASK"):
        run("\tm = BMASK(0)", robot=False)


def test_truncate_stops_at_the_first_nul():
    g = run('\t$a = $TRUNCATE("AB"+$CHR(0)+"CD")\n\t$b = $TRUNCATE("plain")', robot=False).globals
    assert (g["$a"], g["$b"]) == ("AB", "plain")


def test_shift_with_omitted_components_leaves_them_zero():
    g = run("\tSET p = SHIFT(TRANS(1, 2, 3) BY , , 10)\n\tDECOMPOSE d[] = p\n"
            "\tSET q = SHIFT(TRANS(1, 2, 3) BY 5)\n\tDECOMPOSE e[] = q", robot=False).globals
    assert [g["d"][i] for i in range(3)] == [1.0, 2.0, 13.0]
    assert [g["e"][i] for i in range(3)] == [6.0, 2.0, 3.0]


def test_tool_null_removes_the_tool():
    emu = run("\tTOOL TRANS(0, 0, 100)\n\tHERE a\n\tTOOL NULL\n\tHERE b\n\tDECOMPOSE da[] = a\n"
              "\tDECOMPOSE db[] = b")
    da, db = emu.globals["da"], emu.globals["db"]
    # home points the tool down: a 100 mm tool puts its tip 100 mm lower than the flange
    assert da[2] == pytest.approx(db[2] - 100.0, abs=1e-3)
    assert emu.controller.tool.as_tuple() == (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def test_bits_reads_signals_first_as_bit_0():
    g = run("\tSIGNAL 1, -2, 3\n\tb = BITS(1, 3)\n\tBITS 5, 2 = 2\n\tc = SIG(-5, 6)").globals
    assert (g["b"], g["c"]) == (5.0, -1.0)


def _motion_time(body: str) -> float:
    emu2 = emu_of(".PROGRAM t()\n" + body + "\n\tBREAK\n.END\n")
    t0 = emu2.time_s
    emu2.call("t")
    return emu2.time_s - t0


def test_duration_slows_a_short_motion_to_take_that_long_and_only_once_without_always():
    move = "\tMOVE #PPOINT(10, -90, 180, 0, 90, 0)\n\tBREAK\n"
    quick = _motion_time(move)
    assert quick < 0.3
    slow = _motion_time("\tDURATION 2\n" + move)
    assert slow == pytest.approx(2.0, abs=0.05)
    # without ALWAYS only the next motion; with ALWAYS every one
    twice = _motion_time("\tDURATION 1\n" + move + "\tMOVE #PPOINT(0, -90, 180, 0, 90, 0)\n")
    assert twice == pytest.approx(1.0 + quick, abs=0.06)
    always = _motion_time("\tDURATION 1 ALWAYS\n" + move + "\tMOVE #PPOINT(0, -90, 180, 0, 90, 0)\n")
    assert always == pytest.approx(2.0, abs=0.06)


def test_movet_moves_and_operates_the_hand_as_the_motion_starts():
    emu = emu_of(".PROGRAM t()\n\tCLOSEI\n\tMOVET #PPOINT(10, -90, 180, 0, 90, 0), TRUE\n\tBREAK\n"
                 "\tMOVET #PPOINT(0, -90, 180, 0, 90, 0), 0\n\tBREAK\n.END\n"
                 ".PROGRAM o()\n\tMOVET #PPOINT(10, -90, 180, 0, 90, 0), TRUE\n\tBREAK\n.END\n"
                 ".PROGRAM bad()\n\tCLOSEI\n\tMOVET TRANS(5000, 0, 0, 0, 180, 0), TRUE\n.END\n")
    io = emu.controller.io
    emu.call("o")
    assert io.hand_state(emu.time_s) in ("open", "opening") and emu.controller.joints_at(emu.time_s)[0] == pytest.approx(10.0)
    emu.call("t")
    assert io.hand_state(emu.time_s) in ("closed", "closing") and emu.controller.joints_at(emu.time_s)[0] == pytest.approx(0.0)
    # a refused MOVET leaves no hand action behind for a later motion
    with pytest.raises(VPlusError, match="out of range"):
        emu.call("bad")
    assert io.pending_hand is None and io.hand_state(emu.time_s) in ("closed", "closing")
