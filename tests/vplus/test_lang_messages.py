"""Messages that tell a typo from a gap.

A word that is no V+ keyword is a syntax error naming file and line; a V+ keyword the emulator does not implement
says so and names the manual's page (aioadept.vplus.keywords); a run-time error names the file as well as the
program and line.
"""

from __future__ import annotations

import pytest

from aioadept.vplus import Emulator, VPlusError
from aioadept.vplus import keywords


def problems_of(line: str):
    emu = Emulator.from_source(f".PROGRAM p()\n\tx = 1\n\t{line}\n.END\n", filename="cell.V2", robot=False)
    return emu.problems


@pytest.mark.parametrize("line, word", [("MOVEE #pick", "MOVEE"), ("FROBNICATE", "FROBNICATE"),
                                        ("SIGNALL 3", "SIGNALL")])
def test_a_word_that_is_no_v_keyword_is_a_syntax_error_naming_file_and_line(line, word):
    [p] = problems_of(line)
    assert (p.file, p.line, p.word) == ("cell.V2", 3, word)
    assert "syntax error" in p.message and "not a V+ keyword" in p.message
    assert "not implemented" not in p.message
    assert str(p).startswith("cell.V2:3: ")


@pytest.mark.parametrize("line, word, page", [
    ("MOVEC a, b", "MOVEC", "V+ Language Reference Guide v17, MOVEC program instruction"),
    ("SOLVE.ANGLES a[], b = c", "SOLVE.ANGLES", "SOLVE.ANGLES program instruction"),
    ("WINDOW a, b", "WINDOW", "WINDOW program instruction"),
])
def test_a_v_keyword_not_implemented_says_so_and_names_the_manual_page(line, word, page):
    [p] = problems_of(line)
    assert p.word == word and p.line == 3
    assert "not implemented by the emulator" in p.message and page in p.message
    assert "syntax error" not in p.message


def test_a_monitor_command_in_a_program_is_named_as_such():
    [p] = problems_of("LISTL")
    assert "monitor command" in p.message and "V+ Operating System Reference Guide" in p.message


@pytest.mark.parametrize("expr, what", [("FOOBAR(1)", "not a V+ function"),
                                        ("LATCHED(1)", "not implemented by the emulator")])
def test_functions_tell_a_typo_from_a_gap(expr, what):
    [p] = problems_of(f"y = {expr}")
    assert what in p.message and p.line == 3


def test_run_time_errors_name_the_file_program_and_line():
    emu = Emulator.from_source(".PROGRAM p()\n\tx = 1\n\ty = nothing\n.END\n", filename="cell.V2", robot=False)
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    err = info.value
    assert (err.file, err.program, err.line) == ("cell.V2", "p", 3)
    assert "cell.V2" in str(err) and "p" in str(err) and "line 3" in str(err)
    assert any("cell.V2" in line for line in emu.console)


def test_every_instruction_and_function_the_emulator_implements_is_a_v_keyword_or_known_extension():
    from aioadept.vplus import parse

    # the emulator's own extensions, not in the V+ keyword index we read
    extensions = {"$LEFT", "$RIGHT", "$TOUPPER", "$TOLOWER", "RANDOM"}
    missing = {w for w in parse.INSTRUCTIONS | parse.FUNCTIONS if not keywords.is_keyword(w)} - extensions
    assert not missing
