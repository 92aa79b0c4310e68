"""The V+ emulator's language core in virtual time: loader problems, values, control flow, strings, tasks."""

from __future__ import annotations

import pytest

from aioadept.vplus import Emulator, VPlusError


def test_a_bad_line_is_reported_the_rest_loads_and_calling_it_stops_the_task(emu_of):
    emu = emu_of(".PROGRAM good()\n\tx = 1\n.END\n.PROGRAM bad()\n\tx = 2\n\tFROBNICATE 3\n.END\n", strict=False)
    assert [(p.file, p.line, p.word, p.program) for p in emu.problems] == [("t.V2", 6, "FROBNICATE", "bad")]
    emu.call("good")
    assert emu.globals["x"] == 1.0
    with pytest.raises(VPlusError) as info:
        emu.call("bad")
    assert "not executable" in str(info.value) and "t.V2:6" in str(info.value)
    assert any("not executable" in line for line in emu.console)


def test_unbalanced_blocks_make_the_program_not_executable(emu_of):
    emu = emu_of(".PROGRAM p()\n\tIF 1 THEN\n\tx = 1\n.END\n", strict=False)
    assert emu.problems and emu.problems[0].message == "IF not closed"


def test_real_is_single_precision_double_is_not(emu_of):
    emu = emu_of(".PROGRAM p()\n\tAUTO DOUBLE d\n\tGLOBAL DOUBLE g\n\tx = 0.1\n\td = 0.1\n\ty = d\n\tg = 0.1\n.END\n")
    emu.call("p")
    assert emu.globals["x"] != 0.1 and emu.globals["x"] == pytest.approx(0.1, rel=1e-7)
    assert emu.globals["g"] == 0.1


def test_strings_over_128_characters_are_an_error(emu_of):
    emu = emu_of('.PROGRAM p()\n\t$s = "x"\n\tWHILE LEN($s) < 200 DO\n\t\t$s = $s+"x"\n\tEND\n.END\n')
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert "String too long" in str(info.value) and emu.globals["$s"] == "x" * 128


def test_arrays_grow_and_last(emu_of):
    emu = emu_of(".PROGRAM p()\n\ta[3] = 1\n\ta[7] = 2\n\tn = LAST(a[])\n\tm = LAST(b[])\n.END\n")
    emu.call("p")
    assert emu.globals["n"] == 7 and emu.globals["m"] == -1 and emu.globals["a"] == {3: 1.0, 7: 2.0}


def test_arguments_by_reference_for_variables_by_value_for_expressions(emu_of):
    emu = emu_of(".PROGRAM p()\n\tx = 1\n\ty = 1\n\tCALL inc(x)\n\tCALL inc(y+0)\n\tCALL fill(v[])\n.END\n"
                 ".PROGRAM inc(a)\n\ta = a+1\n.END\n.PROGRAM fill(q[])\n\tq[2] = 5\n.END\n")
    emu.call("p")
    assert (emu.globals["x"], emu.globals["y"], emu.globals["v"]) == (2.0, 1.0, {2: 5.0})


def test_names_are_case_insensitive_and_truncated_to_15_characters(emu_of):
    emu = emu_of(".PROGRAM P()\n\tThis_is_a_long_name = 3\n\tz = this_is_a_long_\n.END\n")
    emu.call("p")
    assert emu.globals["z"] == 3.0 and emu.globals["THIS_IS_A_LONG_"] == 3.0


def test_auto_variables_are_local_to_the_call(emu_of):
    emu = emu_of(".PROGRAM p()\n\tAUTO i\n\ti = 5\n\tCALL q()\n.END\n.PROGRAM q()\n\ti = 9\n.END\n")
    emu.call("p")
    assert emu.globals["i"] == 9.0


CONTROL = """.PROGRAM p()
    AUTO i
    s = 0
    FOR i = 10 TO 1 STEP -3
        s = s*10+i
    END
    k = 0
    FOR i = 5 TO 1
        k = k+1
    END
    n = 0
    DO
        n = n+1
        IF n == 2 THEN
            n = n+10
        ELSE
            n = n+1
        END
    UNTIL n > 20
    w = 0
    WHILE TRUE DO
        w = w+1
        IF w < 3 THEN
            NEXT
        END
        EXIT
    END
    CASE w OF
      VALUE 1, 2:
        c = 1
      VALUE 3:
        c = 3
      ANY
        c = 9
    END
.END
"""


def test_structured_control_flow(emu_of):
    emu = emu_of(CONTROL)
    emu.call("p")
    g = emu.globals
    assert (g["s"], g["k"], g["n"], g["w"], g["c"]) == (10741.0, 0.0, 22.0, 3.0, 3.0)


def test_goto_and_labels(emu_of):
    emu = emu_of(".PROGRAM p()\n\tn = 0\n10\tn = n+1\n\tIF n < 5 GOTO 10\n\tGOTO 20\n\tn = 100\n20\tm = n\n.END\n")
    emu.call("p")
    assert emu.globals["m"] == 5.0


def test_string_functions(emu_of):
    emu = emu_of('.PROGRAM p()\n\t$s = "ab,cd,,ef"\n\t$a = $DECODE($s, ",", 0)\n\t$b = $DECODE($s, ",", 1)\n'
                 '\t$e = $ENCODE(/F0.3, -0.0381, ",", /I4, 7, /X2, "x", /F8.2, 3.14159)\n'
                 '\tp = POS("hello", "l")\n\tc = ASC("AB", 2)\n\tv = VAL(" -12.5x")\n\t$m = $MID("hello", 2, 3)\n.END\n')
    emu.call("p")
    g = emu.globals
    assert (g["$a"], g["$b"], g["$s"]) == ("ab", ",", "cd,,ef")
    assert g["$e"] == "-0.038,   7  x    3.14"
    assert (g["p"], g["c"], g["v"], g["$m"]) == (3.0, 66.0, -12.5, "ell")


def test_undefined_value_stops_the_task_with_program_and_line(emu_of):
    emu = emu_of(".PROGRAM p()\n\tx = nothing+1\n.END\n")
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert "Undefined value" in str(info.value) and info.value.line == 2 and info.value.program == "p"


def test_reacte_catches_an_error_and_execution_resumes_after_the_step(emu_of):
    emu = emu_of(".PROGRAM p()\n\tREACTE h\n\tx = 1/0\n\ty = 2\n.END\n.PROGRAM h()\n\te = ERROR(-1, 0)\n"
                 "\t$t = $ERROR(e)\n\tRETURNE\n.END\n")
    emu.call("p")
    assert emu.globals["y"] == 2.0 and emu.globals["e"] < 0 and "Division" in emu.globals["$t"]


def test_tasks_share_globals_and_are_time_sliced(emu_of):
    src = """.PROGRAM main()
    done = FALSE
    n = 0
    EXECUTE 1 worker()
    WHILE NOT done DO
        n = n+1
    END
.END
.PROGRAM worker()
    t = TIMER(-3)
    WAIT TIMER(-3) > t+0.05
    done = TRUE
.END
"""
    emu = emu_of(src)
    emu.call("main")
    # main busy-waits; the worker still runs (slices), virtual time advances by slices until its WAIT ends
    assert emu.globals["done"] == -1.0 and emu.globals["n"] > 1000 and 0.05 <= emu.time_s < 0.2


def test_wait_without_condition_waits_one_cycle_and_type_goes_to_the_console(emu_of):
    emu = emu_of('.PROGRAM p()\n\tWAIT\n\tTYPE "t=", TIMER(-3), /S\n\tTYPE " ok"\n.END\n', cycle_s=0.016)
    emu.call("p", task=3)
    assert emu.console == ["[3] t=0.016 ok"]


def test_calls_by_name_and_undefined_program(emu_of):
    emu = emu_of('.PROGRAM p($n)\n\tCALLS $n(x)\n.END\n.PROGRAM set7(a)\n\ta = 7\n.END\n')
    emu.call("p", "SET7")
    assert emu.globals["x"] == 7.0
    with pytest.raises(VPlusError) as info:
        emu.call("p", "nosuch")
    assert "Undefined program" in str(info.value)


def test_unimplemented_instruction_is_a_load_error_naming_it(emu_of):
    emu = emu_of(".PROGRAM p()\n\tALTER 0.5\n.END\n", strict=False)
    assert emu.problems[0].word == "ALTER" and "not implemented" in emu.problems[0].message


def test_robot_instructions_with_the_simulated_arm():
    emu = Emulator.from_source(".PROGRAM p()\n\tHERE a\n\tDECOMPOSE v[] = a\n\tMOVE a:TRANS(0,0,10)\n\tBREAK\n"
                               "\tHERE b\n\tDECOMPOSE w[] = b\n\tr = INRANGE(TRANS(2000,0,0,0,180,0))\n.END\n")
    emu.call("p")
    v, w = emu.globals["v"], emu.globals["w"]
    assert w[2] == pytest.approx(v[2] - 10, abs=1e-3) and emu.time_s > 0 and emu.globals["r"] != 0
