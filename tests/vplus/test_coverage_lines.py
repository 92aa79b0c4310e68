"""V+ line coverage's pure parts: which lines of a .V2 file are executable, and the file's report for HTML."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("coverage", reason="coverage.py (the test extra) is needed for V+ line coverage")

from aioadept.vplus.coverage_plugin import VPlusPlugin, _hooked, executable_lines  # noqa: E402
from aioadept.vplus.loader import Module, load_text  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted(p for d in ("vplus", "examples") for p in (ROOT / d).rglob("*") if p.suffix.upper() == ".V2")

PROG = (".PROGRAM demo(n, r)\n"       # 1
        "; a comment\n"               # 2
        "    AUTO i\n"                # 3  declaration
        "    r = 0\n"                 # 4
        "    DO\n"                    # 5  DO: no statement of its own
        "        r = r+1\n"           # 6
        "    UNTIL r > n\n"           # 7  UNTIL: tested without a line hook
        "10  CASE r OF\n"             # 8  a label on a statement
        "      VALUE 1:\n"            # 9
        "        r = 2\n"             # 10
        "      ANY\n"                 # 11
        "        GOTO 10\n"           # 12
        "    END\n"                   # 13
        "20\n"                        # 14 a label alone
        "    RETURN\n"                # 15
        ".END\n")


def test_the_executable_lines_are_the_statements_the_compiler_puts_a_line_hook_before():
    assert executable_lines(PROG) == {4, 6, 8, 10, 12, 15}
    # a program that does not compile counts its statements by the compiler's rule, as never run
    assert executable_lines(PROG.replace("GOTO 10", "GOTO 99")) == {4, 6, 8, 10, 12, 15}


def test_the_rule_for_programs_that_do_not_compile_agrees_with_the_compiler_on_every_shipped_file():
    assert len(SHIPPED) >= 10
    for path in SHIPPED:
        text = path.read_text("latin-1")
        rule = {line for prog in load_text(text, path.name, Module()).programs.values()
                for line, st in prog.steps if _hooked(st)}
        assert executable_lines(text, path.name) == rule, path.name


def test_the_plugin_claims_v2_files_and_reports_their_source_line_by_line(tmp_path):
    (tmp_path / "sub").mkdir()
    for name in ("a.V2", "sub/b.pg", "c.py", "d.v2"):
        (tmp_path / name).write_text(PROG)
    plugin = VPlusPlugin()
    assert sorted(Path(f).name for f in plugin.find_executable_files(str(tmp_path))) == ["a.V2", "b.pg", "d.v2"]
    assert plugin.file_tracer(str(tmp_path / "c.py")) is None
    assert plugin.file_tracer(str(tmp_path / "a.V2")).source_filename() == str(tmp_path / "a.V2")
    reporter = plugin.file_reporter(str(tmp_path / "a.V2"))
    assert reporter.lines() == {4, 6, 8, 10, 12, 15}
    tokens = list(reporter.source_token_lines())
    assert ["".join(text for _, text in line) for line in tokens] == PROG.split("\n")
    assert tokens[1] == [("txt", ""), ("com", "; a comment")]
