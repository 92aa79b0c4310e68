"""Every statement of every .V2 file in the repository comes back from its node as its source line (up to
spacing and case), and every node's span points at its own text in that line."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from aioadept.vplus import nodes as N
from aioadept.vplus.loader import load_files
from aioadept.vplus.parse import norm
from aioadept.vplus.unparse import unparse

ROOT = Path(__file__).resolve().parents[2]
FILES = subprocess.run(["git", "ls-files", "*.V2"], cwd=ROOT, capture_output=True, text=True,
                       check=True).stdout.split()


def _same(text: str) -> str:
    return "".join(text.split()).upper()


def _walk(node: N.Node):
    yield node
    for child in node.children():
        yield from _walk(child)


def test_the_repository_has_v2_files():
    assert len(FILES) >= 5


@pytest.mark.parametrize("name", FILES)
def test_each_statement_renders_back_to_its_line_and_each_node_spans_its_text(name):
    path = ROOT / name
    raw = path.read_bytes().decode("latin-1").replace("\r\n", "\n").split("\n")
    module = load_files([path])
    assert not module.problems, [str(p) for p in module.problems]
    checked = 0
    for prog in module.programs.values():
        for line, st in prog.steps:
            source = prog.source[line]
            assert _same(unparse(st)) == _same(source), (name, line, unparse(st), source)
            for node in _walk(st):
                sp = node.span
                assert (sp.file, sp.line) == (path.name, line), (name, line, node)
                text = raw[line - 1][sp.col - 1:sp.end - 1]
                if isinstance(node, (N.Name, N.Index, N.Array)) and not node.parens:
                    # a name is its first 15 characters: compare as V+ does
                    assert norm(text.split("[")[0]) == node.name, (name, line, text, node)
                elif not isinstance(node, N.Stmt) or isinstance(node, N.Label):
                    assert _same(unparse(node)) == _same(text), (name, line, text, unparse(node))
            checked += 1
    assert checked
