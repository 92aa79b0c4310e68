"""The V+ language server (``aioadept vplus lsp``): the real server process driven by a real LSP client.

One server for the module (each start imports pygls and lsprotocol, seconds on a loaded machine); each test
opens main.V2 and closes it at its end."""

from __future__ import annotations

import sys

import pytest
import pytest_asyncio
import pytest_lsp
from lsprotocol import types as T
from pytest_lsp import ClientServerConfig, LanguageClient

MAIN = (".PROGRAM main(n)\n"         # 0 (LSP lines are 0-based)
        "    AUTO x\n"               # 1
        "    x = LEN($s)\n"          # 2
        "    CALL helper(x)\n"       # 3
        "    MOVE a\n"               # 4
        "10  count = count+n\n"      # 5
        "    IF x GOTO 10\n"         # 6
        ".END\n")
HELPER = ("; a second module, only on disk in the workspace folder\n"
          ".PROGRAM helper(n)\n"     # 1
          "    GLOBAL count\n"       # 2
          "    TYPE n, count\n"      # 3
          ".END\n"
          ".PROGRAM again()\n"      # 5
          "    CALL helper(2)\n"    # 6
          ".END\n")


pytestmark = pytest.mark.asyncio(loop_scope="module")


@pytest_lsp.fixture(scope="module", loop_scope="module", config=ClientServerConfig(
    server_command=[sys.executable, "-m", "aioadept.cli", "vplus", "lsp"]))
async def server(lsp_client: LanguageClient, tmp_path_factory):
    tmp_path = tmp_path_factory.mktemp("ws")
    (tmp_path / "helper.V2").write_text(HELPER)
    await lsp_client.initialize_session(T.InitializeParams(
        capabilities=T.ClientCapabilities(),
        workspace_folders=[T.WorkspaceFolder(uri=tmp_path.as_uri(), name="ws")]))
    lsp_client.main_uri = (tmp_path / "main.V2").as_uri()
    lsp_client.helper_uri = (tmp_path / "helper.V2").as_uri()
    yield
    await lsp_client.shutdown_session()


@pytest_asyncio.fixture(loop_scope="module")
async def client(server: LanguageClient):
    yield server
    server.text_document_did_close(T.DidCloseTextDocumentParams(T.TextDocumentIdentifier(server.main_uri)))


async def _open(client: LanguageClient, text: str) -> list[T.Diagnostic]:
    client.text_document_did_open(T.DidOpenTextDocumentParams(T.TextDocumentItem(
        uri=client.main_uri, language_id="vplus", version=1, text=text)))
    await client.wait_for_notification(T.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS)
    return list(client.diagnostics[client.main_uri])


def _at(line: int, character: int) -> T.Position:
    return T.Position(line=line, character=character)


def _loc(uri: str, line: int, start: int, end: int) -> T.Location:
    return T.Location(uri, T.Range(_at(line, start), _at(line, end)))


def _sorted(locations) -> list[T.Location]:
    return sorted(locations, key=lambda loc: (loc.uri, loc.range.start.line, loc.range.start.character))


@pytest.mark.timeout(30)
async def test_diagnostics_on_open_and_on_change_at_the_offending_word(client: LanguageClient):
    opened = sorted(await _open(client, MAIN), key=lambda d: d.range.start.line)
    # the checker's warnings too: nothing assigns $s or a in the workspace (main.V2 and helper.V2 on disk)
    assert [(d.range, d.severity, d.code) for d in opened] == [
        (T.Range(_at(2, 12), _at(2, 14)), T.DiagnosticSeverity.Warning, "W101"),   # LEN([$s])
        (T.Range(_at(4, 9), _at(4, 10)), T.DiagnosticSeverity.Warning, "W101")]    # MOVE [a]
    client.text_document_did_change(T.DidChangeTextDocumentParams(
        T.VersionedTextDocumentIdentifier(uri=client.main_uri, version=2),
        [T.TextDocumentContentChangeWholeDocument(MAIN.replace("MOVE a", "MOVEE a").replace("AUTO x",
                                                                                              "GOTO 77"))]))
    await client.wait_for_notification(T.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS)
    got = sorted((d for d in client.diagnostics[client.main_uri] if d.severity == T.DiagnosticSeverity.Error),
                 key=lambda d: d.range.start.line)
    assert [(d.range, d.severity, d.code) for d in got] == [
        (T.Range(_at(1, 9), _at(1, 11)), T.DiagnosticSeverity.Error, "E001"),     # GOTO [77]
        (T.Range(_at(4, 4), _at(4, 9)), T.DiagnosticSeverity.Error, "E001")]      # [MOVEE] a
    assert "undefined label 77" in got[0].message and "MOVEE is not a V+ keyword" in got[1].message


@pytest.mark.timeout(30)
async def test_hover_and_completion(client: LanguageClient):
    await _open(client, MAIN)
    doc = T.TextDocumentIdentifier(client.main_uri)
    # the form, then the one-line summary with the Reference Guide's section
    move = await client.text_document_hover_async(T.HoverParams(doc, _at(4, 6)))
    assert move.contents.value == ("MOVE location\nMoves the robot to a location, the joints interpolated. "
                                   "(V+ Language Reference Guide v17, MOVE program instruction)")
    length = await client.text_document_hover_async(T.HoverParams(doc, _at(2, 9)))
    assert length.contents.value == ("LEN($string) -> num\nThe number of characters in a string. "
                                     "(V+ Language Reference Guide v17, LEN function)")
    helper = await client.text_document_hover_async(T.HoverParams(doc, _at(3, 10)))
    assert helper.contents.value == ".PROGRAM helper(n) (helper.V2:2)"
    assert await client.text_document_hover_async(T.HoverParams(doc, _at(2, 4))) is None    # x: no V+ word

    got = await client.text_document_completion_async(T.CompletionParams(doc, _at(4, 5)))
    items = {i.label: i for i in got.items}
    assert items["MOVE"].kind == T.CompletionItemKind.Keyword
    assert items["$MID"].kind == T.CompletionItemKind.Function
    assert items["helper"].detail.startswith(".PROGRAM helper(n)")
    assert items["helper"].label_details.detail == "(n)" and items["again"].label_details.detail == "()"
    # in scope in main: its parameter and AUTO (local), and the workspace's globals; not helper's parameter
    variables = {i.label: i.detail for i in got.items if i.kind == T.CompletionItemKind.Variable}
    assert variables == {"n": "local", "x": "local", "$s": "global", "a": "global", "count": "global"}


@pytest.mark.timeout(30)
async def test_definition_references_and_symbols_of_programs_labels_and_variables(client: LanguageClient):
    await _open(client, MAIN)
    doc, main, helper = T.TextDocumentIdentifier(client.main_uri), client.main_uri, client.helper_uri

    async def definition(line: int, character: int):
        return await client.text_document_definition_async(T.DefinitionParams(doc, _at(line, character)))

    async def references(line: int, character: int, declaration: bool = True):
        return _sorted(await client.text_document_references_async(T.ReferenceParams(
            text_document=doc, position=_at(line, character),
            context=T.ReferenceContext(include_declaration=declaration))))

    # a CALL's program, in the other module; its references are the CALLs in both modules
    assert await definition(3, 12) == [_loc(helper, 1, 9, 15)]
    assert await references(3, 12) == _sorted([_loc(helper, 1, 9, 15), _loc(helper, 6, 9, 15),
                                               _loc(main, 3, 9, 15)])
    # a label, in its program
    assert await definition(6, 15) == [_loc(main, 5, 0, 2)]
    assert await references(6, 15) == [_loc(main, 5, 0, 2), _loc(main, 6, 14, 16)]
    # a global: its GLOBAL declaration in the other module; every use of it in the workspace
    assert await definition(5, 13) == [_loc(helper, 2, 11, 16)]
    assert await references(5, 4, declaration=False) == _sorted([
        _loc(main, 5, 4, 9), _loc(main, 5, 12, 17), _loc(helper, 3, 12, 17)])
    # a parameter and an AUTO are their program's own: helper's n is another variable
    assert await definition(5, 18) == [_loc(main, 0, 14, 15)]
    assert await references(5, 18) == [_loc(main, 0, 14, 15), _loc(main, 5, 18, 19)]
    assert await definition(6, 7) == [_loc(main, 1, 9, 10)]
    assert await definition(4, 1) is None                     # blank

    got = await client.text_document_document_symbol_async(T.DocumentSymbolParams(doc))
    assert [(s.name, s.kind, s.selection_range, s.range.end.line, s.detail, [(c.name, c.selection_range)
                                                                             for c in s.children]) for s in got] == [
        ("main", T.SymbolKind.Function, T.Range(_at(0, 9), _at(0, 13)), 7, "n", [("10", T.Range(_at(5, 0),
                                                                                                  _at(5, 2)))])]
    found = await client.workspace_symbol_async(T.WorkspaceSymbolParams(query="C"))
    assert sorted((s.name, s.kind, s.location) for s in found) == [
        ("count", T.SymbolKind.Variable, _loc(helper, 2, 11, 16))]
    found = await client.workspace_symbol_async(T.WorkspaceSymbolParams(query=""))
    assert sorted(s.name for s in found) == ["again", "count", "helper", "main"]
