"""The code generator's fast paths keep V+ semantics: AUTO variables as Python locals (by-reference arguments,
GOTO segments, REACTE resuming, undefined values, DEFINED, $DECODE), $ENCODE compiled at load time, array
indices through the index table."""

from __future__ import annotations

import pytest

from aioadept.vplus import VPlusError
from aioadept.vplus.compiler import _local, compile_program, vplus_name
from aioadept.vplus.loader import Module, load_text


def source_of(src: str, name: str) -> str:
    m = load_text(src, "t.V2", Module())
    code, _, problems = compile_program(m.programs[name], set())
    assert not problems
    return code


def test_an_auto_passed_by_reference_is_written_by_the_callee(emu_of):
    src = """.PROGRAM p()
	AUTO a, b, $s
	a = 1
	CALL inc(a)
	CALL inc(a)
	CALL set(b, $s)
	r = a
	q = b
	$r = $s
.END
.PROGRAM inc(x)
	x = x+1
.END
.PROGRAM set(y, $t)
	y = 7
	$t = "set"
.END
"""
    emu = emu_of(src)
    emu.call("p")
    assert (emu.globals["r"], emu.globals["q"], emu.globals["$r"]) == (3.0, 7.0, "set")
    code = source_of(src, "p")
    assert "(L, 'a')" in code and "(L, 'b')" in code     # passed on by reference: kept in L


def test_an_auto_passed_twice_is_one_variable_in_the_callee(emu_of):
    emu = emu_of(""".PROGRAM p()
	AUTO a
	a = 1
	CALL two(a, a)
	r = a
.END
.PROGRAM two(x, y)
	x = 5
	y = y*2
.END
""")
    emu.call("p")
    assert emu.globals["r"] == 10.0


def test_autos_not_passed_on_are_python_locals():
    code = source_of(".PROGRAM p()\n\tAUTO i, c\n\tFOR i = 1 TO 3\n\t\tc = i*2\n\tEND\n\tr = c\n.END\n", "p")
    assert "L['i']" not in code and "L['c']" not in code and _local("c") in code


def test_locals_survive_goto_segments(emu_of):
    emu = emu_of(""".PROGRAM p()
	AUTO i, s
	i = 0
	s = 0
10	i = i+1
	s = s+i
	IF i < 5 GOTO 10
	GOTO 20
	s = -1
20	r = s
.END
""")
    emu.call("p")
    assert emu.globals["r"] == 15.0


def test_reacte_handler_returns_and_the_program_reads_its_locals(emu_of):
    emu = emu_of(""".PROGRAM p()
	AUTO a, $t
	a = 4
	$t = "kept"
	REACTE h
	x = 1/0
	r = a*2
	$r = $t
.END
.PROGRAM h()
	AUTO a
	a = 99
	seen = 1
	RETURNE
.END
""")
    emu.call("p")
    assert (emu.globals["r"], emu.globals["$r"], emu.globals["seen"]) == (8.0, "kept", 1.0)


def test_an_undefined_auto_is_an_undefined_value_with_its_name(emu_of):
    emu = emu_of(".PROGRAM p()\n\tAUTO $id.x, n\n\tn = 1\n\tr = LEN($id.x)\n.END\n")
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert "*Undefined value* $id.x" in str(info.value) and info.value.line == 4


def test_an_undefined_auto_caught_by_reacte_resumes(emu_of):
    emu = emu_of(".PROGRAM p()\n\tAUTO u\n\tREACTE h\n\tr = u+1\n\tr = 2\n.END\n"
                 ".PROGRAM h()\n\tc = ERROR(-1, 0)\n\tRETURNE\n.END\n")
    emu.call("p")
    assert emu.globals["r"] == 2.0 and emu.globals["c"] < 0


def test_defined_and_decode_of_autos(emu_of):
    emu = emu_of(""".PROGRAM p()
	AUTO a, $l, $w
	d1 = DEFINED(a)
	a = 1
	d2 = DEFINED(a)
	$l = "ab:cd"
	$w = $DECODE($l, ":", 0)
	$r1 = $w
	$r2 = $l
.END
""")
    emu.call("p")
    g = emu.globals
    assert (g["d1"], g["d2"], g["$r1"], g["$r2"]) == (0.0, -1.0, "ab", ":cd")


def test_local_names_map_back_one_to_one():
    for name in ("c", "$id", "rs.x", "a_b", "$a.b_c", "#p", "x_d", "x.d"):
        assert vplus_name(_local(name)) == name
    assert _local("x_d") != _local("x.d")


def test_compiled_encode_matches_the_general_formatter(emu_of):
    emu = emu_of(""".PROGRAM p()
	AUTO v
	v = -0.0375
	$a = $ENCODE(/F0.3, v, ",", /F0.3, 2, ",", /F8.2, 3.14159, /X2, "s", /I4, 7.6, /D, 1.5, ",", 42)
	$b = $ENCODE(/F0.3, "str", v)
.END
""")
    emu.call("p")
    assert emu.globals["$a"] == "-0.038,2.000,    3.14  s   8" + "1.5,42"
    assert emu.globals["$b"] == "str-0.038"


def test_encode_with_an_unknown_format_fails_when_it_runs(emu_of):
    emu = emu_of(".PROGRAM p()\n\t$a = $ENCODE(/Q3, 1)\n.END\n")
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert "format" in str(info.value)


def test_array_indices_fractional_and_negative(emu_of):
    # a fractional index is rounded (V+ Language User's Guide v17, p. 102): a[2.4] is a[2] (a[2.7] would be a[3])
    emu = emu_of(".PROGRAM p()\n\ta[2] = 5\n\tr = a[2.4]\n\ti = 5000\n\tb[i] = 1\n\tr2 = b[5000]\n\tq = a[-1]\n.END\n")
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert emu.globals["r"] == 5.0 and emu.globals["r2"] == 1.0
    assert "Illegal array index" in str(info.value)
