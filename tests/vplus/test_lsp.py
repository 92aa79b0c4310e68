"""The V+ language server (``aioadept vplus lsp``): the real server process driven by a real LSP client."""

from __future__ import annotations

import sys

import pytest
import pytest_lsp
from lsprotocol import types as T
from pytest_lsp import ClientServerConfig, LanguageClient

MAIN = (".PROGRAM main()\n"          # 0 (LSP lines are 0-based)
        "    AUTO x\n"               # 1
        "    x = LEN($s)\n"          # 2
        "    CALL helper(x)\n"       # 3
        "    MOVE a\n"               # 4
        ".END\n")
HELPER = ("; a second module, only on disk in the workspace folder\n"
          ".PROGRAM helper(n)\n"     # 1
          "    TYPE n\n"
          ".END\n"
          ".PROGRAM again()\n"      # 4
          "    CALL helper(2)\n"    # 5
          ".END\n")


@pytest_lsp.fixture(config=ClientServerConfig(server_command=[sys.executable, "-m", "aioadept.cli", "vplus",
                                                              "lsp"]))
async def client(lsp_client: LanguageClient, tmp_path):
    (tmp_path / "helper.V2").write_text(HELPER)
    await lsp_client.initialize_session(T.InitializeParams(
        capabilities=T.ClientCapabilities(),
        workspace_folders=[T.WorkspaceFolder(uri=tmp_path.as_uri(), name="ws")]))
    lsp_client.main_uri = (tmp_path / "main.V2").as_uri()
    yield
    await lsp_client.shutdown_session()


async def _open(client: LanguageClient, text: str) -> list[T.Diagnostic]:
    client.text_document_did_open(T.DidOpenTextDocumentParams(T.TextDocumentItem(
        uri=client.main_uri, language_id="vplus", version=1, text=text)))
    await client.wait_for_notification(T.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS)
    return list(client.diagnostics[client.main_uri])


def _at(line: int, character: int) -> T.Position:
    return T.Position(line=line, character=character)


@pytest.mark.timeout(30)
async def test_diagnostics_on_open_and_on_change_at_the_offending_word(client: LanguageClient):
    assert await _open(client, MAIN) == []
    client.text_document_did_change(T.DidChangeTextDocumentParams(
        T.VersionedTextDocumentIdentifier(uri=client.main_uri, version=2),
        [T.TextDocumentContentChangeWholeDocument(MAIN.replace("MOVE a", "MOVEE a").replace("AUTO x",
                                                                                              "GOTO 77"))]))
    await client.wait_for_notification(T.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS)
    got = sorted(client.diagnostics[client.main_uri], key=lambda d: d.range.start.line)
    assert [(d.range, d.severity) for d in got] == [
        (T.Range(_at(1, 9), _at(1, 11)), T.DiagnosticSeverity.Error),     # GOTO [77]
        (T.Range(_at(4, 4), _at(4, 9)), T.DiagnosticSeverity.Error)]      # [MOVEE] a
    assert "undefined label 77" in got[0].message and "MOVEE is not a V+ keyword" in got[1].message


@pytest.mark.timeout(30)
async def test_hover_gives_the_form_and_manual_section_of_an_instruction_and_a_function(client: LanguageClient):
    await _open(client, MAIN)
    move = await client.text_document_hover_async(T.HoverParams(T.TextDocumentIdentifier(client.main_uri),
                                                                _at(4, 6)))
    assert move.contents.value.startswith("MOVE location (") and "MOVE program instruction" in move.contents.value
    length = await client.text_document_hover_async(T.HoverParams(T.TextDocumentIdentifier(client.main_uri),
                                                                  _at(2, 9)))
    assert length.contents.value.startswith("LEN($string) -> num (") and "LEN" in length.contents.value
    assert await client.text_document_hover_async(T.HoverParams(T.TextDocumentIdentifier(client.main_uri),
                                                                _at(2, 4))) is None    # x: no V+ word


@pytest.mark.timeout(30)
async def test_completion_offers_instructions_functions_and_the_workspace_programs(client: LanguageClient):
    await _open(client, MAIN)
    got = await client.text_document_completion_async(T.CompletionParams(
        T.TextDocumentIdentifier(client.main_uri), _at(4, 5)))
    items = {i.label: i for i in got.items}
    assert items["MOVE"].kind == T.CompletionItemKind.Keyword
    assert items["$MID"].kind == T.CompletionItemKind.Function
    assert items["helper"].detail.startswith(".PROGRAM helper(n)")


@pytest.mark.timeout(30)
async def test_definition_of_a_call_target_is_its_program_line_in_the_other_module(client: LanguageClient,
                                                                                     tmp_path):
    await _open(client, MAIN)
    got = await client.text_document_definition_async(T.DefinitionParams(
        T.TextDocumentIdentifier(client.main_uri), _at(3, 12)))
    assert got == T.Location(uri=(tmp_path / "helper.V2").as_uri(), range=T.Range(_at(1, 0), _at(1, 0)))


@pytest.mark.timeout(30)
async def test_references_of_a_program_are_its_calls_in_both_modules_and_its_declaration(client: LanguageClient,
                                                                                         tmp_path):
    await _open(client, MAIN)
    got = await client.text_document_references_async(T.ReferenceParams(
        text_document=T.TextDocumentIdentifier(client.main_uri), position=_at(3, 12),
        context=T.ReferenceContext(include_declaration=True)))
    helper = (tmp_path / "helper.V2").as_uri()
    assert sorted(got, key=lambda loc: (loc.uri, loc.range.start.line)) == sorted([
        T.Location(helper, T.Range(_at(1, 0), _at(1, 0))),
        T.Location(helper, T.Range(_at(5, 9), _at(5, 15))),
        T.Location(client.main_uri, T.Range(_at(3, 9), _at(3, 15)))], key=lambda loc: (loc.uri, loc.range.start.line))


@pytest.mark.timeout(30)
async def test_document_symbols_are_the_documents_programs(client: LanguageClient):
    await _open(client, MAIN + ".PROGRAM second(a, $b)\n    TYPE a\n.END\n")
    got = await client.text_document_document_symbol_async(T.DocumentSymbolParams(
        T.TextDocumentIdentifier(client.main_uri)))
    assert [(s.name, s.kind, s.selection_range.start.line, s.range.end.line, s.detail) for s in got] == [
        ("main", T.SymbolKind.Function, 0, 5, ""), ("second", T.SymbolKind.Function, 6, 8, "a, $b")]
