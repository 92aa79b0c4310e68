"""The V+ TextMate grammar (editors/vscode/syntaxes/vplus.tmLanguage.json) run by the real engine, VS Code's
vscode-textmate with Oniguruma (npm, pinned in tests/integration/textmate_node/package-lock.json), over every
.V2 file of the repository. What each token should be comes from the emulator's own reading of the same lines
(the loader's programs, the parser's tokens and statement nodes), so the grammar is held to the language as the
emulator parses it: comments, strings, numbers (radix constants too), a statement's instruction, the built-in
functions called, step labels and GOTO targets, program names on .PROGRAM lines and as CALL, EXECUTE and
REACTE targets, and variables (never coloured as keywords); and no line ends inside an open scope."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from aioadept.vplus import nodes as N
from aioadept.vplus.loader import Module, load_text, strip_comment
from aioadept.vplus.parse import tokenize

from npmtree import npm_tree

ROOT = Path(__file__).resolve().parents[2]
GRAMMAR = ROOT / "editors" / "vscode" / "syntaxes" / "vplus.tmLanguage.json"
SAMPLE = """.PROGRAM radix.demo(a, $b, c[])
; every numeric form of the V+ Language User's Guide v17, "Numeric Representation", and the power operator
    AUTO x, y
    x = ^B1001+^346+^H23FF+^D20000000
    y = x^2+a ^3-1.5E+3+.25+'A
    $b = $MID("a;b", 1, 1)        ; a ; in a string starts no comment
    IF x > 0 GOTO 10
10  CALL radix.demo(x, $b, c[])
    EXECUTE 2, radix.demo(y, $b, c[])
.END
"""
"""Forms no shipped file uses, read by the same engine and held to the same parser."""
FILES = subprocess.run(["git", "ls-files", "*.V2", "*.v2", "*.pg"], cwd=ROOT, capture_output=True, text=True,
                       check=True).stdout.split()


@pytest.fixture(scope="module")
def scopes(tmp_path_factory) -> dict[str, list[dict]]:
    """Each file's lines as the engine tokenizes them (the sample's by its full path)."""
    sample = tmp_path_factory.mktemp("grammar") / "sample.V2"
    sample.write_text(SAMPLE)
    tree = npm_tree(Path(__file__).resolve().parent / "textmate_node", "textmate-node", what="TEXTMATE GRAMMAR TEST")
    proc = subprocess.run(["node", str(tree / "tokenize.mjs"), str(GRAMMAR), "source.vplus", *FILES, str(sample)],
                          cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def _expected(file: str) -> list[tuple[int, int, int, str, str]]:
    """``(line, start, end, scope prefix, what)``: 1-based line, 0-based columns of a token and the scope it must
    have (a prefix of one of its scopes; ``!keyword`` means none may start with ``keyword`` or ``support``)."""
    text = (ROOT / file).read_text("latin-1")
    lines = text.split("\n")
    out = []
    for n, raw in enumerate(lines, 1):
        code = strip_comment(raw)
        if len(code) < len(raw):
            out.append((n, len(code), len(raw.rstrip("\r")), "comment.line.semicolon", "comment"))
    module = load_text(text, file, Module())
    assert not module.problems, module.problems
    for prog in module.programs.values():
        head = lines[prog.line - 1]
        k = head.lower().index(prog.name[:8], head.upper().index(".PROGRAM") + 8)
        out.append((prog.line, k, k + len(prog.name), "entity.name.function", "program name"))
        for line, stmt in prog.steps:
            out += _step_expected(prog, line, stmt)
    return out


def _step_expected(prog, line: int, stmt: N.Node) -> list[tuple[int, int, int, str, str]]:
    """The tokens of one step: its strings and constants, label, instruction, GOTO target, program called, and
    the functions, numbers and variables of its tree."""
    out = []
    indent, toks = prog.indent[line], tokenize(prog.source[line])
    at = {indent + t.col: t for t in toks}
    for t in toks:
        a, b = indent + t.col, indent + t.col + len(t.text)
        if t.kind == "str":
            out.append((line, a, b, "string.quoted.double", "string"))
        elif t.kind == "num" and t.text.startswith("^"):
            out.append((line, a, b, "constant.numeric", "radix constant"))
        elif t.kind == "num" and t.text.startswith("'"):
            out.append((line, a, b, "constant.character", "ASCII constant"))
    inner = stmt
    if isinstance(stmt, N.Label):
        t = toks[0]
        out.append((line, indent + t.col, indent + t.col + len(t.text), "entity.name.label", "label"))
        toks, inner = toks[1:], stmt.stmt
    if inner is None:
        return out
    first = toks[0]
    if not isinstance(inner, N.Assign):
        out.append((line, indent + first.col, indent + first.col + len(first.text), "keyword",
                    "instruction"))
    if isinstance(inner, (N.Goto, N.IfGoto)):
        t = toks[-1]
        out.append((line, indent + t.col, indent + t.col + len(t.text), "entity.name.label", "GOTO target"))
    if isinstance(inner, (N.CallStmt, N.Execute, N.Reacte)):
        t = next(t for t in toks[1:] if t.kind == "name" and t.text.lower().startswith(inner.name[:8]))
        out.append((line, indent + t.col, indent + t.col + len(t.text), "entity.name.function",
                    "program called"))
    out += _tree_expected(line, stmt, at)
    return out


def _tree_expected(line: int, stmt: N.Node, at: dict) -> list[tuple[int, int, int, str, str]]:
    """The functions called, numbers and variables of a step's tree (``at``: its tokens by column)."""
    out = []
    stack: list[N.Node] = [stmt]
    while stack:
        node = stack.pop()
        stack.extend(node.children())
        t = at.get(node.span.col - 1)
        if t is None:
            continue
        a, b = node.span.col - 1, node.span.col - 1 + len(t.text)
        if isinstance(node, N.Call) and not node.bare:
            out.append((line, a, b, "support.function", "function called"))
        elif isinstance(node, N.Num) and t.kind == "num" and not t.text.startswith(("^", "'")):
            out.append((line, a, b, "constant.numeric", "number"))
        elif isinstance(node, (N.Name, N.Index, N.Array)):
            out.append((line, a, b, "!keyword", "variable"))
    return out


def _scopes_of(tokens: list, start: int, end: int) -> list[list[str]]:
    """The scopes of every engine token overlapping ``[start, end)``."""
    return [s for a, b, s in tokens if a < end and b > start]


def test_every_v2_file_gets_its_scopes_from_the_real_textmate_engine(scopes):
    assert len(FILES) >= 10 and set(FILES) < set(scopes) and len(scopes) == len(FILES) + 1
    wrong, counts = [], {}
    for file in scopes:
        lines = scopes[file]
        for n, line in enumerate(lines, 1):
            if line["depth"] != 1:
                wrong.append(f"{file}:{n}: the line ends inside an open scope (rule stack depth {line['depth']})")
        for n, a, b, want, what in _expected(file):
            counts[what] = counts.get(what, 0) + 1
            got = _scopes_of(lines[n - 1]["tokens"], a, b)
            if want == "!keyword":
                ok = not any(s.startswith(("keyword", "support")) for ss in got for s in ss)
            else:
                ok = bool(got) and all(any(s.startswith(want) for s in ss) for ss in got)
            if not ok:
                wrong.append(f"{file}:{n}:{a + 1}: {what} should be {want}: {got}")
    assert not wrong, "\n".join(wrong[:40]) + f"\n({len(wrong)} in all)"
    # every kind of token was seen, in numbers that show the whole files were read
    assert counts["comment"] > 500 and counts["string"] > 300 and counts["instruction"] > 1000
    assert counts["radix constant"] >= 5 and counts["ASCII constant"] >= 1 and counts["label"] >= 2 and counts["GOTO target"] >= 2
    assert counts["program called"] > 150 and counts["function called"] > 100 and counts["variable"] > 2000
    assert counts["program name"] > 100 and counts["number"] > 500

