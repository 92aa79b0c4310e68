"""Every problem of a file at once: each with its line and the column of the offending word."""

from __future__ import annotations

from aioadept.vplus.emulator import Emulator

# (source line, message fragment, offending word): one mistake per program, the line indented by 4 spaces
MISTAKES = [
    ("MOVEE a", "MOVEE is not a V+ keyword", "MOVEE"),
    ("x = 1 +* 2", "unexpected '*'", "*"),
    ("GOTO 20", "GOTO to an undefined label 20", "20"),
    ("x = 1\n    END", "END without an open block", "END"),
    ("x = 1\n    IF x THEN", "IF not closed", "IF"),
    ("x = 1\n    AUTO a", "AUTO after an executable instruction", "AUTO"),
    ("AUTO q", "q is a parameter", "q"),
    ("$s = $DECODE(1, 2)", "$DECODE needs a string variable", "$DECODE"),
    ("n = 2 * LAST(a)", "LAST needs an array", "LAST"),
    ("x = y + to", "keyword TO used as a name", "to"),
]


def _source() -> tuple[str, list[tuple[int, int]]]:
    lines, where = [], []
    for k, (code, _, word) in enumerate(MISTAKES):
        lines.append(f".PROGRAM p{k}(q)")
        for part in code.split("\n"):
            lines.append(part if part.startswith("    ") else "    " + part)
        last = lines[-1]
        where.append((len(lines), last.upper().index(word.upper(), 4) + 1))
        lines.append(".END")
    return "\n".join(lines) + "\n", where


def test_ten_mistakes_in_ten_programs_are_ten_problems_each_at_its_line_and_column():
    text, where = _source()
    emu = Emulator.from_source(text, filename="ten.V2", robot=False)
    got = sorted(emu.problems, key=lambda p: p.line)
    assert len(got) == 10, [str(p) for p in got]
    for prob, (code, message, word), (line, col) in zip(got, MISTAKES, where, strict=True):
        assert message in prob.message, (code, str(prob))
        assert (prob.file, prob.line, prob.column) == ("ten.V2", line, col), (code, str(prob), prob.column)
        assert prob.word.upper() == word.upper()


def test_every_problem_of_one_program_is_reported_not_only_the_first():
    text = ("\t.PROGRAM p()\n"
            "\tGOTO 10\n"
            "\tx = LAST(a)\n"
            "\tELSE\n"
            "\tMOVEE a\n"
            "\ty = 1 = 2\n"
            "\t.END\n")
    emu = Emulator.from_source(text, filename="one.V2", robot=False)
    got = sorted((p.line, p.column, p.word) for p in emu.problems)
    assert got == [(2, 7, "10"), (3, 6, "LAST"), (4, 2, "ELSE"), (5, 2, "MOVEE"), (6, 8, "=")], \
        [str(p) for p in emu.problems]
