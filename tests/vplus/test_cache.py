"""Parsed files and compiled programs are cached by content: emulators built from the same text share code,
never data; a changed text is parsed and compiled again."""

from __future__ import annotations

from aioadept.vplus import Emulator
from aioadept.vplus import loader, runtime

SRC = ".PROGRAM p()\n\tn = n+1\n\t$s = $ENCODE(/F0.1, n)\n.END\n"


def test_emulators_of_the_same_text_share_code_not_data():
    a = Emulator.from_source(SRC, filename="c.V2", robot=False)
    b = Emulator.from_source(SRC, filename="c.V2", robot=False)
    assert a.rt.programs["p"].__code__ is b.rt.programs["p"].__code__       # compiled once
    a.globals["n"] = 5
    b.globals["n"] = 0
    a.call("p")
    b.call("p")
    assert (a.globals["n"], a.globals["$s"]) == (6.0, "6.0")
    assert (b.globals["n"], b.globals["$s"]) == (1.0, "1.0")


def test_a_changed_text_is_parsed_and_compiled_again(tmp_path):
    f = tmp_path / "m.V2"
    f.write_text(".PROGRAM p()\n\tx = 1\n.END\n")
    assert Emulator.load(f, robot=False).call("p") and True
    e1 = Emulator.load(f, robot=False)
    e1.call("p")
    f.write_text(".PROGRAM p()\n\tx = 2\n.END\n")
    e2 = Emulator.load(f, robot=False)
    e2.call("p")
    assert (e1.globals["x"], e2.globals["x"]) == (1.0, 2.0)
    assert loader._PARSED and runtime._COMPILED
