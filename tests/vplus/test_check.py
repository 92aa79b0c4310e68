"""``aioadept vplus check``: every problem of V+ files at its line and column, for a terminal and for CI."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from aioadept.vplus.check import _problem, check

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted(p for d in ("vplus", "examples") for p in (ROOT / d).rglob("*") if p.suffix.upper() == ".V2")

# three programs, four mistakes (one file): (line, column, message fragment)
BAD = (".PROGRAM one()\n"          # 1
       "    MOVEE a\n"             # 2  not a keyword
       "    x = 1 +* 2\n"          # 3  unexpected *
       ".END\n"
       ".PROGRAM two()\n"          # 5
       "    GOTO 20\n"             # 6  no label 20
       ".END\n"
       ".PROGRAM three(q)\n"       # 8
       "    AUTO q\n"              # 9  q is a parameter
       ".END\n")
WANT = [(2, 5, "MOVEE is not a V+ keyword"), (3, 12, "unexpected '*'"), (6, 10, "GOTO to an undefined label 20"),
        (9, 10, "q is a parameter")]


def run_cli(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "aioadept.cli", "vplus", "check", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=60)


def test_every_shipped_v2_file_checks_clean_together_and_the_cli_prints_nothing():
    assert len(SHIPPED) >= 10
    assert check((str(p), p.read_text("latin-1")) for p in SHIPPED) == []
    done = run_cli("vplus", "examples")
    assert (done.returncode, done.stdout, done.stderr) == (0, "", "")


def test_a_file_with_several_mistakes_gives_each_at_its_line_and_column(tmp_path):
    got = check([("bad.V2", BAD)])
    assert [(p.file, p.line, p.column, p.severity) for p in got] == [("bad.V2", ln, col, "error")
                                                                      for ln, col, _ in WANT]
    for p, (_, _, fragment) in zip(got, WANT):
        assert fragment in p.message
    (tmp_path / "bad.V2").write_text(BAD)
    done = run_cli("bad.V2", cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    lines = done.stdout.splitlines()
    assert [ln.split(": error: ")[0] for ln in lines] == [f"bad.V2:{ln}:{col}" for ln, col, _ in WANT]
    assert all(fragment in ln for ln, (_, _, fragment) in zip(lines, WANT))


def test_the_github_format_is_one_error_annotation_per_problem(tmp_path):
    (tmp_path / "bad.V2").write_text(BAD)
    done = run_cli("--format", "github", "bad.V2", cwd=tmp_path)
    assert done.returncode == 1
    lines = done.stdout.splitlines()
    assert lines[0] == ("::error file=bad.V2,line=2,col=5,endColumn=10::syntax error: MOVEE is not a V+ keyword "
                        "in one [MOVEE]")
    ends = [p.end_column for p in check([("bad.V2", BAD)])]
    assert [ln.split("::")[1] for ln in lines] == [f"error file=bad.V2,line={ln},col={col},endColumn={end}"
                                                   for (ln, col, _), end in zip(WANT, ends)]


def test_the_json_format_is_one_array_of_the_problems(tmp_path):
    (tmp_path / "bad.V2").write_text(BAD)
    done = run_cli("--format", "json", "bad.V2", cwd=tmp_path)
    assert done.returncode == 1
    got = json.loads(done.stdout)
    assert [(d["file"], d["line"], d["column"], d["severity"]) for d in got] == [("bad.V2", ln, col, "error")
                                                                               for ln, col, _ in WANT]
    assert got[0]["end_column"] == 10 and "MOVEE is not a V+ keyword" in got[0]["message"]


@pytest.mark.parametrize("args, needle", [(["missing.V2"], "missing.V2: no such file"),
                                          (["empty"], "empty: no V+ files")])
def test_a_cli_mistake_is_one_line_naming_the_path_and_exit_2(tmp_path, args, needle):
    (tmp_path / "empty").mkdir()
    done = run_cli(*args, cwd=tmp_path)
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.strip() == f"aioadept vplus check: {needle}" + (" (.v2, .pg) in this folder"
                                                                       if args == ["empty"] else "")


def test_after_each_edit_check_gives_exactly_what_the_emulator_refuses_at_load_time():
    """check keeps the problems of unchanged pieces of a file between calls: after every edit (a line changed,
    one inserted on top, a mistake mended, a program left open) they are still those of a fresh load."""
    from aioadept.vplus.emulator import Emulator

    text = (ROOT / "vplus" / "rsskills.V2").read_text("latin-1")
    middle = text.count("\n") // 2
    lines = text.split("\n")
    edits = [text, BAD + text,
             "\n".join(lines[:middle] + ["    MOVEE a"] + lines[middle + 1:]),
             "\n".join(lines[:middle] + ["    MOVEE a"] + lines[middle + 1:]).replace("\n", "\n; one more\n", 1),
             text.replace(".END", "", 1), text]
    counts = []
    for edited in edits:
        fresh = {str(_problem(p)) for p in Emulator.from_source(edited, filename="e.V2", robot=False).problems}
        got = [str(p) for p in check([("e.V2", edited)])]
        assert sorted(got) == sorted(fresh)
        counts.append(len(got))
    assert counts[0] == counts[-1] == 0 and all(counts[1:-1]), counts
