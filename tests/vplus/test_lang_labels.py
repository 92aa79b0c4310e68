"""Step labels anywhere V+ allows them: inside WHILE, FOR, DO, IF and CASE bodies, a GOTO to
the end of a loop body as "continue", GOTO out of blocks, EXIT/NEXT next to labels; a GOTO into a block is
refused at load (V+'s rule is not in the manuals we have: the safe side). UG p. 35: "program steps can contain a
step label", any step."""

from __future__ import annotations

from aioadept.vplus import Emulator
from aioadept.vplus.debugger import Debugger


def run(body: str) -> dict:
    emu = Emulator.from_source(".PROGRAM t()\n" + body + "\n.END\n", filename="l.V2", strict=True, robot=False)
    emu.call("t")
    return emu.globals


def problems(body: str) -> list[tuple[int, str]]:
    emu = Emulator.from_source(".PROGRAM t()\n" + body + "\n.END\n", filename="l.V2", robot=False)
    return [(p.line, p.message) for p in emu.problems]


def test_goto_the_end_of_a_loop_body_is_continue():
    g = run("\tn = 0\n\ts = 0\n"
            "\tWHILE n < 10 DO\n"
            "\t\tn = n+1\n"
            "\t\tIF n MOD 2 == 0 GOTO 10\n"          # even: skip the sum
            "\t\ts = s+n\n"
            "10\tEND\n"                               # the label on the END line: the end of the body
            "\tk = 0\n"
            "\tFOR i = 1 TO 6\n"
            "\t\tIF i == 3 GOTO 20\n"
            "\t\tk = k+i\n"
            "20\n"                                    # a label alone at the end of the FOR body
            "\tEND")
    assert (g["n"], g["s"]) == (10.0, 25.0)         # 1+3+5+7+9
    assert (g["i"], g["k"]) == (7.0, 18.0)          # 21 - 3; the FOR still counts to its end


def test_goto_out_of_nested_blocks_and_back_to_an_enclosing_bodys_label():
    g = run("\tc = 0\n"
            "\tWHILE TRUE DO\n"
            "\t\tFOR j = 1 TO 100\n"
            "\t\t\tc = c+1\n"
            "\t\t\tCASE j OF\n"
            "\t\t\t  VALUE 3:\n"
            "\t\t\t\tGOTO 50\n"                       # out of CASE, FOR and WHILE to the program's label
            "\t\t\tEND\n"
            "\t\tEND\n"
            "\t\tc = 1000\n"
            "\tEND\n"
            "\tc = 2000\n"
            "50\tm = 1\n"
            "\tr = 0\n"
            "\tIF m THEN\n"
            "30\t\tr = r+1\n"                         # a loop made of a label inside an IF body
            "\t\tIF r < 4 THEN\n"
            "\t\t\tGOTO 30\n"                         # out of the inner IF, back in the outer one's body
            "\t\tEND\n"
            "\tEND")
    assert (g["c"], g["j"], g["m"], g["r"]) == (3.0, 3.0, 1.0, 4.0)


def test_exit_and_next_in_a_loop_body_that_has_labels():
    g = run("\ts = 0\n"
            "\tFOR i = 1 TO 10\n"
            "\t\tIF i == 2 THEN\n"
            "\t\t\tNEXT\n"                            # in a labelled body: across its dispatch
            "\t\tEND\n"
            "\t\tIF i == 5 THEN\n"
            "\t\t\tEXIT\n"
            "\t\tEND\n"
            "\t\tIF i == 3 GOTO 40\n"
            "\t\ts = s+i\n"
            "40\t\tu = i\n"
            "\tEND\n"
            "\tw = 0\n"
            "\tDO\n"
            "\t\tw = w+1\n"
            "\t\tIF w < 3 GOTO 60\n"
            "\t\tEXIT\n"
            "60\tUNTIL w > 100\n")                    # the label on UNTIL: the test
    assert (g["s"], g["u"], g["i"]) == (5.0, 4.0, 5.0)   # 1 + 4; u last set at i = 4
    assert g["w"] == 3.0


def test_labels_in_case_arms():
    g = run("\tr = 0\n"
            "\tFOR v = 1 TO 3\n"
            "\t\tCASE v OF\n"
            "\t\t  VALUE 1:\n"
            "70\t\t\tr = r+1\n"                     # a loop inside one arm
            "\t\t\tIF r < 5 GOTO 70\n"
            "\t\t  ANY\n"
            "\t\t\tIF v == 2 THEN\n"
            "\t\t\t\tGOTO 80\n"                     # out of the IF to a label of the arm
            "\t\t\tEND\n"
            "\t\t\tr = r+100\n"
            "80\t\t\tr = r+10\n"
            "\t\tEND\n"
            "\tEND")
    assert g["r"] == 125.0                          # 5, then +10 (v = 2), then +110 (v = 3)


def test_a_goto_into_a_block_or_a_duplicate_label_is_refused_at_load():
    assert problems("\tGOTO 10\n\tWHILE TRUE DO\n10\t\tx = 1\n\tEND") == [
        (2, "GOTO 10 into a block (IF, CASE, WHILE, DO or FOR) the GOTO is not in is not supported by the emulator")]
    assert problems("\tIF 1 THEN\n\t\tGOTO 80\n\tELSE\n80\t\tx = 1\n\tEND")[0][0] == 3    # THEN to ELSE
    assert problems("10\tx = 1\n\tIF x THEN\n10\t\ty = 2\n\tEND\n\tGOTO 10") == [
        (4, "label 10 is defined twice")]
    assert problems("\tFOR i = 1 TO 2\n10\t\tx = i\n\tEND\n\tIF x < 5 GOTO 10")[0][0] == 5


def test_a_breakpoint_in_a_loop_with_a_label_stops_there(tmp_path):
    src = tmp_path / "b.V2"
    src.write_text(".PROGRAM t()\n\tn = 0\n\tWHILE n < 3 DO\n\t\tn = n+1\n\t\tIF n == 2 GOTO 10\n"
                   "\t\tm = n\n10\tEND\n.END\n")
    emu = Emulator.load(src, robot=False)
    d = Debugger(emu.rt)
    (bp,) = d.set_breakpoints(str(src), [{"line": 6}])          # m = n, inside the labelled body
    assert bp.verified
    emu.execute(0, "t")
    seen = []
    for _ in range(2):
        emu.run(5.0, until=lambda: 0 in d.stopped)
        assert 0 in d.stopped
        seen.append((d.frames(0)[0].line, emu.globals["n"]))
        d.resume(0)
    emu.run(5.0, until=lambda: "m" in emu.globals and emu.globals["m"] == 3.0 and 0 not in d.stopped)
    assert seen == [(6, 1.0), (6, 3.0)]                          # n = 2 jumped over it


def test_blocks_nested_too_deep_for_the_emulator_are_a_problem_not_a_crash():
    depth = 6                                   # six labelled loops: four Python blocks each, over Python's 20
    body = "".join(f"\tx{i} = 0\n" for i in range(depth))
    for i in range(depth):
        body += f"\tWHILE x{i} < 1 DO\n\t\tx{i} = x{i}+1\n\t\tIF x{i} < 0 GOTO {10 + i}\n{10 + i}\n"
    body += "\tEND\n" * depth
    assert problems(body) == [(1, "blocks nested too deep for the emulator (Python: too many statically nested "
                                  "blocks)")]
