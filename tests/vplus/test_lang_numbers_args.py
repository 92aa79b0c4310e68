"""Numbers and arguments as V+ does them.

- V+ Language User's Guide v17, p. 102 (Real and Integer Data Types): "If an integer is required and you supply a
  real, V+ promotes the real to an integer by rounding (not truncation)".
- p. 45 (Undefined Arguments): an argument left blank (``a, , c``) or omitted at the end of the list "is passed as
  undefined"; the subroutine tests it with ``DEFINED``.
- p. 44 (Call by value): "Real numbers and integers are surrounded by parentheses, :NULL is appended to location
  variables, and +"" is appended to string variables" to pass a variable by value.
"""

from __future__ import annotations

import pytest

from aioadept.vplus import VPlusError


def test_an_array_index_is_rounded_not_truncated(emu_of):
    emu = emu_of(".PROGRAM p()\n\ta[1.6] = 5\n\ti = 2.4\n\tb[i] = 7\n\tj = 0.5\n\tc[j] = 1\n"
                 "\tx = a[i-0.2]\n\tDECOMPOSE d[0.7] = TRANS(1,2,3,0,0,0)\n.END\n")
    emu.call("p")
    g = emu.globals
    assert g["a"] == {2: 5.0} and g["b"] == {2: 7.0} and g["c"] == {1: 1.0} and g["x"] == 5.0
    assert g["d"][1] == 1.0 and 0 not in g["d"]


@pytest.mark.parametrize("expr, want", [
    ('$CHR(65.6)', "B"), ('$CHR(65.4)', "A"), ('$MID("abcdef", 1.6, 2.5)', "bcd"),
    ('$CHR(ASC("abc", 1.5)+0.5)', "c"), ('$LEFT("abcdef", 2.5)', "abc"), ('$RIGHT("abcdef", 1.7)', "ef"),
])
def test_string_functions_round_their_integer_arguments(emu_of, expr, want):
    emu = emu_of(f".PROGRAM p()\n\t$s = {expr}\n.END\n")
    emu.call("p")
    assert emu.globals["$s"] == want


def test_pos_rounds_its_start(emu_of):
    emu = emu_of('.PROGRAM p()\n\tn = POS("abcabc", "a", 1.6)\n.END\n')
    emu.call("p")
    assert emu.globals["n"] == 4.0


def test_a_negative_index_after_rounding_is_an_error(emu_of):
    emu = emu_of(".PROGRAM p()\n\ti = -0.6\n\ta[i] = 1\n.END\n")
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert "Illegal array index" in str(info.value)


SUB = """.PROGRAM sub(a, b, c, q[])
\tda = DEFINED(a)
\tdb = DEFINED(b)
\tdc = DEFINED(c)
\tdq = DEFINED(q[])
\tIF NOT DEFINED(b) THEN
\t\tb = 99
\tEND
.END
"""


def test_blank_and_omitted_arguments_are_undefined_in_the_callee_every_call(emu_of):
    emu = emu_of(".PROGRAM p()\n\tx = 1\n\tCALL sub(x, , x)\n\tr1 = da*1000+db*100+dc*10+dq\n"
                 "\tCALL sub(x)\n\tr2 = da*1000+db*100+dc*10+dq\n\tCALL sub(, x)\n\tr3 = da*1000+db*100+dc*10+dq\n"
                 ".END\n" + SUB)
    emu.call("p")
    g = emu.globals
    # TRUE is -1: DEFINED(a) and DEFINED(c) only; then only a; then only b
    assert (g["r1"], g["r2"], g["r3"]) == (-1010.0, -1000.0, -100.0)
    assert g["x"] == 1.0      # the callee's write to its undefined b went nowhere


def test_reading_an_omitted_argument_is_undefined_value_naming_it(emu_of):
    emu = emu_of(".PROGRAM p()\n\tCALL s2()\n.END\n.PROGRAM s2(v)\n\ty = v\n.END\n")
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert "Undefined value" in str(info.value) and " v" in str(info.value)


def test_a_variable_in_parentheses_is_passed_by_value(emu_of):
    emu = emu_of('.PROGRAM p()\n\tx = 1\n\ty = 1\n\tz = 1\n\t$s = "a"\n\tCALL inc((x), y, (z)+0, $s+"")\n.END\n'
                 '.PROGRAM inc(a, b, c, $t)\n\ta = a+1\n\tb = b+1\n\tc = c+1\n\t$t = "b"\n.END\n')
    emu.call("p")
    g = emu.globals
    assert (g["x"], g["y"], g["z"], g["$s"]) == (1.0, 2.0, 1.0, "a")


def test_a_blank_argument_of_execute_is_undefined_in_the_task(emu_of):
    emu = emu_of(".PROGRAM p()\n\tx = 1\n\tEXECUTE 1 sub(x, , x)\n.END\n" + SUB)
    emu.call("p")
    emu.run(0.1)
    g = emu.globals
    assert (g["da"], g["db"], g["dc"], g["dq"]) == (-1.0, 0.0, -1.0, 0.0)


def test_defined_of_a_parameter_passed_by_value_is_true_whatever_its_value(emu_of):
    emu = emu_of(".PROGRAM p()\n\tx = 1\n\tCALL sub((x), 2, x+1)\n.END\n" + SUB)
    emu.call("p")
    g = emu.globals
    assert (g["da"], g["db"], g["dc"], g["dq"]) == (-1.0, -1.0, -1.0, 0.0)
