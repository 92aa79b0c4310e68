"""Every V+ function and instruction the emulator implements has a one-line summary for hover."""

from __future__ import annotations

from aioadept.vplus import registry


def test_every_function_and_instruction_has_a_one_line_summary_and_its_hover_shows_it_with_the_section():
    entries = [*registry.FUNCTIONS.values(), *registry.INSTRUCTIONS.values()]
    assert len(entries) > 150
    for entry in entries:
        assert entry.summary and "\n" not in entry.summary and entry.summary.endswith("."), entry.name
        assert len(entry.summary) <= 120, entry.name
    # a word that is both: the function where it is a function, the instruction where it stands first
    assert registry.hover("speed") == ("SPEED(select) -> num\n" + registry.FUNCTIONS["SPEED"].summary
                                       + " (V+ Language Reference Guide v17, SPEED function)")
    assert registry.hover("SPEED", instruction=True).splitlines() == [
        "SPEED value [ALWAYS]",
        registry.INSTRUCTIONS["SPEED"].summary + " (V+ Language Reference Guide v17, SPEED program instruction)"]
    assert registry.hover("NOSUCH") is None
