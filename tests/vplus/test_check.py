"""``aioadept vplus check``: every problem of V+ files at its line and column, for a terminal and for CI."""

from __future__ import annotations

import json
import re
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
    """The real ``aioadept vplus check`` process."""
    return subprocess.run([sys.executable, "-m", "aioadept.cli", "vplus", "check", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=60)


def cli(capsys, *args: str) -> subprocess.CompletedProcess:
    """``aioadept vplus check`` in this process (its output formats; the real process is run_cli's)."""
    from aioadept.cli.vplus import main

    capsys.readouterr()
    rc = main(["check", *args])
    out = capsys.readouterr()
    return subprocess.CompletedProcess(args, rc, out.out, out.err)


def test_every_shipped_v2_file_checks_clean_together_and_the_cli_prints_nothing():
    assert len(SHIPPED) >= 10
    assert check((str(p), p.read_text("latin-1")) for p in SHIPPED) == []
    done = run_cli("vplus", "examples")
    assert (done.returncode, done.stdout, done.stderr) == (0, "", "")


def test_a_file_with_several_mistakes_gives_each_at_its_line_and_column(tmp_path):
    got = check([("bad.V2", BAD)])
    assert [(p.file, p.line, p.column, p.severity) for p in got] == [("bad.V2", ln, col, "error")
                                                                      for ln, col, _ in WANT]
    for p, (_, _, fragment) in zip(got, WANT, strict=True):
        assert fragment in p.message
    (tmp_path / "bad.V2").write_text(BAD)
    done = run_cli("bad.V2", cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    lines = done.stdout.splitlines()
    assert [ln.split(": error: ")[0] for ln in lines] == [f"bad.V2:{ln}:{col}" for ln, col, _ in WANT]
    assert all(fragment in ln for ln, (_, _, fragment) in zip(lines, WANT, strict=True))


def test_the_github_format_is_one_error_annotation_per_problem(tmp_path, capsys, monkeypatch):
    (tmp_path / "bad.V2").write_text(BAD)
    monkeypatch.chdir(tmp_path)
    done = cli(capsys, "--format", "github", "bad.V2")
    assert done.returncode == 1
    lines = done.stdout.splitlines()
    assert lines[0] == ("::error file=bad.V2,line=2,col=5,endColumn=10,title=E001::syntax error: MOVEE is not a "
                        "V+ keyword in one [MOVEE] [E001]")
    ends = [p.end_column for p in check([("bad.V2", BAD)])]
    assert [ln.split("::")[1] for ln in lines] == [f"error file=bad.V2,line={ln},col={col},endColumn={end},title=E001"
                                                   for (ln, col, _), end in zip(WANT, ends, strict=True)]


def test_the_json_format_is_one_array_of_the_problems(tmp_path, capsys, monkeypatch):
    (tmp_path / "bad.V2").write_text(BAD)
    monkeypatch.chdir(tmp_path)
    done = cli(capsys, "--format", "json", "bad.V2")
    assert done.returncode == 1
    got = json.loads(done.stdout)
    assert [(d["file"], d["line"], d["column"], d["severity"], d["code"]) for d in got] == [
        ("bad.V2", ln, col, "error", "E001") for ln, col, _ in WANT]
    assert got[0]["end_column"] == 10 and "MOVEE is not a V+ keyword" in got[0]["message"]


@pytest.mark.parametrize("args, needle", [(["missing.V2"], "missing.V2: no such file"),
                                          (["empty"], "empty: no V+ files")])
def test_a_cli_mistake_is_one_line_naming_the_path_and_exit_2(tmp_path, capsys, monkeypatch, args, needle):
    (tmp_path / "empty").mkdir()
    monkeypatch.chdir(tmp_path)
    done = cli(capsys, *args)
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


# -- warnings ---------------------------------------------------------------------------------

# Two modules: each warning once, at a known line and column, and around them every way a variable gets a value
# that must not be taken for a read of nothing (parameters, AUTO, LOCAL, a global assigned in the other module,
# arrays, READ/PROMPT targets, HERE, SET, DECOMPOSE, FOR, a by-reference CALL argument, data sections).
MAIN = (".PROGRAM main(p, arr[])\n"                              # 1
        "    AUTO a, unused, buf[4]\n"                             # 2  W104 unused (col 13)
        "    LOCAL st\n"                                          # 3
        "    a = p + arr[1] + other + tbl[2] + fromdata\n"        # 4  other: assigned in lib.V2
        "    st = a + nosuch\n"                                   # 5  W101 nosuch (col 14)
        "    READ (1) $line\n"                                    # 6
        "    PROMPT \"n? \", n\n"                                 # 7
        "    HERE #pp\n"                                          # 8
        "    SET spot = HERE\n"                                   # 9
        "    DECOMPOSE buf[] = spot\n"                            # 10
        "    FOR i = 1 TO LEN($line)\n"                           # 11
        "        TYPE $line, n, buf[0], i, $DECODE($line, \",\", 0)\n"  # 12
        "    END\n"                                               # 13
        "    CALL fill(out)\n"                                    # 14
        "    TYPE out, DEFINED(maybe)\n"                          # 15
        "    MOVE #pp\n"                                          # 16
        "    MOVE home\n"                                         # 17
        "    CALL absent(1)\n"                                    # 18 W102 absent (col 10)
        "    CALL fill(out, 2)\n"                                 # 19 W107 fill (col 10)
        "10  TYPE \"" + "x" * 129 + "\"\n"                          # 20 W103 label 10 (col 1), W106 (col 10)
        "    RETURN\n"                                            # 21
        "    TYPE \"never\"\n"                                    # 22 W105 (col 5)
        "    TYPE \"nor this\"\n"                                 # 23 (the same run: reported once)
        ".END\n"
        ".LOCATIONS\n"
        "home 0 0 500 0 180 0\n"
        ".END\n"
        ".REALS\n"
        "fromdata 3\n"
        ".END\n")
LIB = (".PROGRAM fill(x)\n"                                       # 1
       "    x = 1\n"                                              # 2
       "    other = 2\n"                                          # 3
       "    tbl[2] = 3\n"                                         # 4
       "    IF x > 0 THEN\n"                                      # 5
       "        RETURN\n"                                         # 6
       "    ELSE\n"                                               # 7  reached: the IF's other arm
       "        GOTO 20\n"                                        # 8
       "    END\n"                                                # 9
       "    x = 3\n"                                              # 10 reached: after the IF
       "20  x = x + 1\n"                                          # 11
       ".END\n")
WARNED = [("main.V2", 2, 13, "W104", "AUTO unused is never used in main"),
          ("main.V2", 5, 14, "W101", "nosuch is read in main but nothing assigns it"),
          ("main.V2", 18, 10, "W102", "main calls absent, which no loaded module defines"),
          ("main.V2", 19, 10, "W107", "main calls fill with 2 arguments; its .PROGRAM line declares 1"),
          ("main.V2", 20, 1, "W103", "label 10 in main: nothing jumps to it"),
          ("main.V2", 20, 10, "W106", "a string constant of 129 characters in main: V+ takes at most 128"),
          ("main.V2", 22, 5, "W105", "unreachable in main: nothing reaches this line after the RETURN on line 21")]


def _found(problems) -> list[tuple]:
    return [(p.file, p.line, p.column, p.code, p.message) for p in problems]


def test_each_warning_at_its_line_and_column_with_its_code_and_none_where_a_variable_gets_a_value():
    got = check([("main.V2", MAIN), ("lib.V2", LIB)], warnings=True)
    assert all(p.severity == "warning" for p in got)
    assert [f[:4] for f in _found(got)] == [w[:4] for w in WARNED]
    for p, w in zip(got, WARNED, strict=True):
        assert w[4] in p.message
    assert check([("main.V2", MAIN), ("lib.V2", LIB)]) == []        # warnings only when asked for


def test_what_one_module_alone_lacks_is_warned_and_an_auto_or_local_is_its_own_programs():
    alone = _found(check([("main.V2", MAIN)], warnings=True))
    assert [(ln, code) for _, ln, _, code, _ in alone if code in ("W101", "W102")] == [
        (4, "W101"), (4, "W101"), (5, "W101"), (14, "W102"), (18, "W102"), (19, "W102")]
    # an AUTO or LOCAL is not the global of the same name: assigned in another program, it is still unassigned
    mod = (".PROGRAM one()\n    LOCAL k\n    AUTO $s\n    TYPE k, $s\n.END\n"
           ".PROGRAM two()\n    k = 1\n    $s = \"a\"\n.END\n")
    assert [(ln, col, code) for _, ln, col, code, _ in _found(check([("m.V2", mod)], warnings=True))] == [
        (4, 10, "W101"), (4, 13, "W101")]


def test_a_check_ignore_comment_silences_the_named_warning_on_its_line_only():
    lines = MAIN.split("\n")
    lines[4] += "   ; check: ignore W101"          # nosuch
    lines[17] += " ; CHECK: ignore W101, W103"      # absent: W102 is not named, it stays
    lines[19] += " ; check: ignore"                 # every warning of the line
    got = [(p.line, p.code) for p in check([("main.V2", "\n".join(lines)), ("lib.V2", LIB)], warnings=True)]
    assert got == [(2, "W104"), (18, "W102"), (19, "W107"), (22, "W105")]
    # an error is what V+ refuses to load: no comment silences it
    assert [p.code for p in check([("bad.V2", BAD.replace("MOVEE a", "MOVEE a ; check: ignore"))],
                                  warnings=True)] == ["E001"] * 4


def test_check_document_gives_one_documents_problems_with_the_workspace_as_context():
    from aioadept.vplus.check import check_document

    bad_lib = LIB + ".PROGRAM broken()\n    MOVEE a\n.END\n"
    got = check_document("main.V2", MAIN, [("lib.V2", bad_lib), ("main.V2", "stale text on disk")])
    assert [f[:4] for f in _found(got)] == [w[:4] for w in WARNED]      # lib.V2's own error is not reported
    assert [p.code for p in check_document("main.V2", MAIN)].count("W101") == 3


# -- mistakes planted in a copy of the shipped server, all reported in one run --------------

PLANTED = [  # (program, a line of it to plant after, the planted line, its code, the column of its word)
    ("rs.halt", "rs.run = FALSE", "\tMOVEE rs.x", "E001", 2),                       # a syntax error
    ("rs.arm", "HERE #rs.jh", "\tIF rs.njnt > 99 GOTO 999", "E001", 23),            # GOTO a missing label
    ("rs.qused", "n = rs.qtail-rs.qhead", "\tCALL rs.nothere(n)", "W102", 7),       # CALL a missing program
    ("rs.qused", "n = rs.qtail-rs.qhead", "\tn = n+rs.typo", "W101", 8),            # read of a never-assigned
    ("rs.pop", "AUTO i", "\tCALL rs.qused(i, k)", "W107", 7),                       # more arguments than declared
]


def plant(text: str, program: str, anchor: str, new: str) -> str:
    """``text`` with the line ``new`` inserted after the first line holding ``anchor`` in ``program``."""
    lines = text.split("\n")
    start = next(i for i, ln in enumerate(lines) if ln.startswith(f".PROGRAM {program}("))
    at = next(i for i in range(start, len(lines)) if anchor in lines[i])
    return "\n".join(lines[:at + 1] + [new] + lines[at + 1:])


def test_mistakes_planted_in_a_copy_of_rserver_are_each_reported_at_its_line_with_its_code_in_one_run(tmp_path):
    for f in (ROOT / "vplus").glob("*.V2"):
        (tmp_path / f.name).write_bytes(f.read_bytes())
    text = (ROOT / "vplus" / "rserver.V2").read_text("latin-1")
    for program, anchor, new, _, _ in PLANTED:
        text = plant(text, program, anchor, new)
    (tmp_path / "rserver.V2").write_text(text, "latin-1")
    lines = text.split("\n")
    want = sorted((lines.index(new) + 1, col, code) for _, _, new, code, col in PLANTED)
    done = run_cli("rserver.V2", "rsconfig.V2", "rsskills.V2", "rsstate.V2", cwd=tmp_path)
    assert done.returncode == 1, done.stderr          # errors among them
    got = [re.fullmatch(r"rserver\.V2:(\d+):(\d+): (error|warning): .* \[(\w+)\]", ln) for ln in
           done.stdout.splitlines()]
    assert all(got), done.stdout
    assert [(int(m[1]), int(m[2]), m[4]) for m in got] == want, done.stdout
    assert [m[3] for m in got] == ["error" if code == "E001" else "warning" for _, _, code in want]


# SARIF 2.1.0's required properties and value ranges, as its schema (OASIS, sarif-schema-2.1.0.json) states
# them for the objects the check writes: sarifLog, run, tool, toolComponent, reportingDescriptor, result,
# message, location, physicalLocation, artifactLocation, region.
SARIF_REQUIRED = {
    "type": "object", "required": ["version", "runs"],
    "properties": {
        "version": {"enum": ["2.1.0"]},
        "runs": {"type": "array", "items": {"$ref": "#/definitions/run"}}},
    "definitions": {
        "run": {"type": "object", "required": ["tool"], "properties": {
            "tool": {"type": "object", "required": ["driver"],
                     "properties": {"driver": {"$ref": "#/definitions/toolComponent"}}},
            "columnKind": {"enum": ["utf16CodeUnits", "unicodeCodePoints"]},
            "results": {"type": "array", "items": {"$ref": "#/definitions/result"}}}},
        "toolComponent": {"type": "object", "required": ["name"], "properties": {
            "name": {"type": "string"}, "version": {"type": "string"},
            "rules": {"type": "array", "uniqueItems": True, "items": {
                "type": "object", "required": ["id"], "properties": {
                    "id": {"type": "string"}, "shortDescription": {"$ref": "#/definitions/message"},
                    "defaultConfiguration": {"type": "object", "properties": {
                        "level": {"enum": ["none", "note", "warning", "error"]}}}}}}}},
        "message": {"type": "object", "anyOf": [{"required": ["text"]}, {"required": ["id"]}],
                    "properties": {"text": {"type": "string"}}},
        "result": {"type": "object", "required": ["message"], "properties": {
            "message": {"$ref": "#/definitions/message"}, "ruleId": {"type": "string"},
            "ruleIndex": {"type": "integer", "minimum": -1},
            "level": {"enum": ["none", "note", "warning", "error"]},
            "locations": {"type": "array", "items": {"type": "object", "properties": {"physicalLocation": {
                "type": "object", "anyOf": [{"required": ["address"]}, {"required": ["artifactLocation"]}],
                "properties": {
                    "artifactLocation": {"type": "object", "properties": {"uri": {"type": "string"}}},
                    "region": {"type": "object", "properties": {
                        "startLine": {"type": "integer", "minimum": 1},
                        "startColumn": {"type": "integer", "minimum": 1},
                        "endColumn": {"type": "integer", "minimum": 1}}}}}}}}}}}}


def test_the_sarif_format_is_a_sarif_2_1_0_log_with_a_rule_and_a_located_result_per_problem(tmp_path, capsys,
                                                                                           monkeypatch):
    import jsonschema

    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "main.V2").write_text(MAIN)
    (tmp_path / "src" / "lib.V2").write_text(LIB + BAD)
    monkeypatch.chdir(tmp_path)
    done = cli(capsys, "--format", "sarif", "src")
    assert done.returncode == 1                          # BAD's errors
    log = json.loads(done.stdout)
    jsonschema.Draft7Validator(SARIF_REQUIRED).validate(log)
    (run,) = log["runs"]
    rules = run["tool"]["driver"]["rules"]
    assert {r["id"] for r in rules} >= {"E001", "W101", "W102", "W103", "W104", "W105", "W106", "W107"}
    want = check([("src/lib.V2", LIB + BAD), ("src/main.V2", MAIN)], warnings=True)
    assert len(run["results"]) == len(want) == 4 + len(WARNED)
    for r, p in zip(run["results"], want, strict=True):
        assert rules[r["ruleIndex"]]["id"] == r["ruleId"] == p.code
        assert r["level"] == p.severity and r["message"]["text"] == p.message
        (loc,) = r["locations"]
        assert loc["physicalLocation"]["artifactLocation"]["uri"] == p.file       # relative, as given
        assert loc["physicalLocation"]["region"] == {"startLine": p.line, "startColumn": p.column,
                                                     "endColumn": p.end_column}
