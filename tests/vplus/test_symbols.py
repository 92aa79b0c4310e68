"""Where V+ names are defined and used (aioadept.vplus.symbols), over the shipped V+ files."""

from __future__ import annotations

from pathlib import Path

from aioadept.vplus.symbols import LABEL, PROGRAM, USE, VARIABLE, Workspace

ROOT = Path(__file__).resolve().parents[2]


def _workspace(*globs: str) -> Workspace:
    return Workspace((str(p), p.read_text("latin-1")) for g in globs for p in sorted(ROOT.glob(g)))


def test_every_call_and_goto_of_the_shipped_code_resolves_to_one_definition_at_the_named_word():
    ws = _workspace("vplus/*.V2", "examples/vplus/cell/*.V2")
    uses = [o for o in ws.occurrences() if o.role == USE and o.kind in (PROGRAM, LABEL)]
    assert len([o for o in uses if o.kind == LABEL]) >= 2 and len(uses) > 150
    lines = {f: Path(f).read_text("latin-1").split("\n") for f in ws.files}
    for use in uses:
        defs = ws.definitions(use)
        assert len(defs) == 1, use
        word = lines[defs[0].file][defs[0].line - 1][defs[0].col - 1:defs[0].end - 1]
        assert word.lower() == use.name, (use, defs)
        assert lines[use.file][use.line - 1][use.col - 1:use.end - 1].lower() == use.name


def test_a_parameter_is_its_programs_own_and_a_global_is_shared_by_the_modules():
    ws = Workspace([("a.V2", ".PROGRAM a(n)\n    g = n\n.END\n"),
                    ("b.V2", ".PROGRAM b(n)\n    LOCAL k\n    k = g+n\n.END\n")])
    n_in_b = ws.at("b.V2", 3, 11)
    assert (n_in_b.kind, n_in_b.name) == (VARIABLE, "n")
    assert [(o.file, o.line) for o in ws.references(n_in_b)] == [("b.V2", 1), ("b.V2", 3)]
    g = ws.at("b.V2", 3, 9)
    assert [(o.file, o.line, o.col) for o in ws.definitions(g)] == [("a.V2", 2, 5)]    # assigned, not declared
    assert ws.in_scope("b.V2", 3) == (["k", "n"], ["g"])
    assert [o.name for o in ws.symbols()] == ["a", "b"]
