"""The VS Code extension's declarations (editors/vscode/) agree with what they name: the grammar file is what
editors/make_grammar.py writes from the V+ keyword tables, the debugger's launch attributes are the ones
``aioadept vplus dap`` reads, and the language's files are the ones the language server reads."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

from aioadept.vplus import daplaunch, keywords, lsp

ROOT = Path(__file__).resolve().parents[2]
VSCODE = ROOT / "editors" / "vscode"


def _make_grammar():
    spec = importlib.util.spec_from_file_location("make_grammar", ROOT / "editors" / "make_grammar.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_grammar_file_is_what_make_grammar_writes_and_knows_every_v_plus_instruction_and_function():
    grammar = VSCODE / "syntaxes" / "vplus.tmLanguage.json"
    assert grammar.read_text() == _make_grammar().text(), "run python editors/make_grammar.py"
    rules = json.loads(grammar.read_text())["repository"]
    start = re.compile(rules["statement-start"]["match"])
    jumps = re.compile(rules["call"]["match"]), re.compile(rules["goto"]["match"]), re.compile(
        rules["execute"]["match"])
    for word in sorted(keywords.INSTRUCTIONS):
        line = f"    {word} x1 ; {word.lower()}"
        assert start.match(line) or any(j.search(f"{line}()") or j.search(f"    {word} 10") for j in jumps), word
        assert not start.match(f"    {word.lower()} = 1"), word        # a variable that looks like it
    calls = next(re.compile(p["match"]) for p in rules["expression"]["patterns"]
                 if p.get("name") == "support.function.vplus" and "(?=" in p["match"])
    for word in sorted(keywords.FUNCTIONS):
        assert calls.search(f"x = {word}(1)"), word
        assert not calls.search(f"x = rs.{word.lower().lstrip('$#')}(1)"), word


def test_the_extension_launches_what_the_debug_adapter_reads_and_opens_what_the_server_reads():
    pkg = json.loads((VSCODE / "package.json").read_text())
    contributes = pkg["contributes"]
    debugger, = contributes["debuggers"]
    assert debugger["type"] == "vplus"
    assert set(debugger["configurationAttributes"]["launch"]["properties"]) == daplaunch.LAUNCH_KEYS
    for config in debugger["initialConfigurations"]:
        assert set(config) - {"type", "request", "name"} <= daplaunch.LAUNCH_KEYS
    language, = contributes["languages"]
    assert {e.lower() for e in language["extensions"]} == set(lsp.SUFFIXES)
    assert contributes["grammars"][0]["path"] == "./syntaxes/vplus.tmLanguage.json"
    assert json.loads((VSCODE / "language-configuration.json").read_text())["comments"]["lineComment"] == ";"
    assert (VSCODE / pkg["main"]).is_file()
    assert '"vplus", "lsp"' in (VSCODE / "extension.js").read_text()
    assert '"vplus", "dap"' in (VSCODE / "extension.js").read_text()
