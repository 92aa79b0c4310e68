"""One registry of V+ functions feeds the parser, the code generator's result types, the run time's table and
hover text."""

from __future__ import annotations

import pytest

from aioadept.vplus import nodes as N
from aioadept.vplus import registry
from aioadept.vplus.compiler import _SPECIAL_CALLS
from aioadept.vplus.emulator import Emulator
from aioadept.vplus.parse import VSyntaxError, parse_statement


def test_every_registered_function_has_a_form_a_result_a_section_and_an_implementation():
    emu = Emulator.from_source(".PROGRAM p()\n.END\n", robot=False)
    table = emu.rt._namespace()["_fn"]
    for name, entry in registry.FUNCTIONS.items():
        assert entry.form.startswith(name) and entry.result in ("num", "str", "loc", "pp"), entry
        assert entry.section, entry
        if name != "SHIFT" and name not in _SPECIAL_CALLS:     # their code is generated, not a call
            assert name in table, name
    assert registry.describe("$mid") == \
        "$MID($string, first, count) -> str (V+ Language Reference Guide v17, $MID function)"


def test_a_registered_function_parses_as_a_call_and_an_unregistered_keyword_is_named_not_implemented():
    assert isinstance(parse_statement("x = FRACT(1.5)").value, N.Call)
    with pytest.raises(VSyntaxError) as info:
        parse_statement("x = OUTSIDE(1)")
    assert info.value.message == ("V+ function OUTSIDE is not implemented by the emulator "
                                  "(see V+ Language Reference Guide v17, OUTSIDE function)")
    assert info.value.col == 5


def test_the_result_type_of_a_call_comes_from_the_registry():
    # a location function's value must be assigned with SET; a number's must not
    emu = Emulator.from_source(".PROGRAM p()\n  x = INVERSE(a)\n  y = DX(a)\n.END\n", filename="t.V2", robot=False)
    assert [(p.line, p.column, p.message) for p in emu.problems] == \
        [(2, 3, "a location is assigned with SET (SET name = value)")]


def test_the_registry_has_a_form_for_every_instruction_the_parser_knows_and_no_other():
    from aioadept.vplus.parse import STATEMENTS

    assert set(registry.INSTRUCTIONS) == set(STATEMENTS)
    assert registry.describe("appro", instruction=True) == \
        "APPRO location, distance (V+ Language Reference Guide v17, APPRO program instruction)"
    assert registry.describe("MOVEC", instruction=True) is None
