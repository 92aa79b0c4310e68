"""``aioadept vplus lsp``: the V+ Language Server (stdio), a thin adapter over the language core.

- diagnostics of a document on open, change and save: :func:`aioadept.vplus.check.check`;
- hover on an instruction or function name: its form and manual section (:func:`aioadept.vplus.registry.describe`);
- completion: the registry's instructions and functions and the workspace's program names;
- go to definition of a program name (a ``CALL`` target): its ``.PROGRAM`` line in the open documents or the
  workspace folder's V+ files, loaded by :mod:`aioadept.vplus.loader`; its references (the ``CALL``s of it);
- document symbols: the document's programs.

Needs the ``lsp`` extra (pygls, lsprotocol).
"""

from __future__ import annotations

import re
from pathlib import Path

from lsprotocol import types as T
from pygls.lsp.server import LanguageServer
from pygls.uris import from_fs_path, to_fs_path

from aioadept import __version__
from aioadept.vplus import registry
from aioadept.vplus.check import check
from aioadept.vplus.loader import Module, load_text
from aioadept.vplus.nodes import CallStmt
from aioadept.vplus.parse import norm

SUFFIXES = (".v2", ".pg")
_WORD = re.compile(r"[$#]?[A-Za-z][A-Za-z0-9._]*")

server = LanguageServer("aioadept-vplus", __version__)


def _path(uri: str) -> str:
    return to_fs_path(uri) or uri


@server.feature(T.TEXT_DOCUMENT_DID_OPEN)
@server.feature(T.TEXT_DOCUMENT_DID_CHANGE)
@server.feature(T.TEXT_DOCUMENT_DID_SAVE)
def _changed(ls: LanguageServer, params) -> None:
    uri = params.text_document.uri
    doc = ls.workspace.get_text_document(uri)
    ls.text_document_publish_diagnostics(
        T.PublishDiagnosticsParams(uri=uri, version=doc.version, diagnostics=diagnostics(_path(uri), doc.source)))


def diagnostics(name: str, text: str) -> list[T.Diagnostic]:
    """The problems of one document as LSP diagnostics (0-based ranges at the offending word)."""
    return [T.Diagnostic(range=T.Range(T.Position(p.line - 1, p.column - 1), T.Position(p.line - 1,
                                                                                        p.end_column - 1)),
                         message=p.message, severity=T.DiagnosticSeverity.Error, source="aioadept vplus")
            for p in check([(name, text)])]


def word_at(line: str, character: int) -> tuple[str, int] | None:
    """The V+ name (``$MID``, ``rs.poll``) that the 0-based ``character`` of ``line`` is in, and where it starts."""
    for m in _WORD.finditer(line):
        if m.start() <= character <= m.end():
            return m.group(), m.start()
    return None


def _word(ls: LanguageServer, params) -> tuple[str, str, int] | None:
    doc = ls.workspace.get_text_document(params.text_document.uri)
    lines = doc.lines
    if params.position.line >= len(lines):
        return None
    line = lines[params.position.line]
    found = word_at(line, params.position.character)
    return (line, *found) if found else None


@server.feature(T.TEXT_DOCUMENT_HOVER)
def hover(ls: LanguageServer, params: T.HoverParams) -> T.Hover | None:
    found = _word(ls, params)
    if found is None:
        return None
    line, word, start = found
    # the statement's first word is an instruction (MOVE), any other a function (SIG( ... ) ; a name that is
    # both (TIMER, SPEED) is described as what it is where it stands
    first = line[:start].strip() == "" or re.fullmatch(r"\s*\d+\s*", line[:start]) is not None
    text = (registry.describe(word, instruction=first) or registry.describe(word, instruction=not first))
    if text is None:
        return None
    return T.Hover(contents=T.MarkupContent(kind=T.MarkupKind.PlainText, value=text))


@server.feature(T.TEXT_DOCUMENT_COMPLETION)
def completion(ls: LanguageServer, params: T.CompletionParams) -> T.CompletionList:
    items = [T.CompletionItem(label=name, kind=T.CompletionItemKind.Keyword, detail=registry.describe(
        name, instruction=True)) for name in registry.INSTRUCTIONS]
    items += [T.CompletionItem(label=name, kind=T.CompletionItemKind.Function, detail=registry.describe(name))
              for name in registry.FUNCTIONS if name not in registry.INSTRUCTIONS]
    for prog in workspace_module(ls).programs.values():
        args = ", ".join(p.name + ("[]" if p.is_array else "") for p in prog.params)
        items.append(T.CompletionItem(label=prog.name, kind=T.CompletionItemKind.Module,
                                      detail=f".PROGRAM {prog.name}({args}) ({Path(prog.file).name})"))
    return T.CompletionList(is_incomplete=False, items=items)


@server.feature(T.TEXT_DOCUMENT_DEFINITION)
def definition(ls: LanguageServer, params: T.DefinitionParams) -> T.Location | None:
    found = _word(ls, params)
    if found is None:
        return None
    prog = workspace_module(ls).programs.get(norm(found[1]))
    if prog is None:
        return None
    return _location(prog.file, prog.line, 0, 0)


_CALL = re.compile(r"\bCALL\s+([A-Za-z][A-Za-z0-9._]*)", re.IGNORECASE)


@server.feature(T.TEXT_DOCUMENT_REFERENCES)
def references(ls: LanguageServer, params: T.ReferenceParams) -> list[T.Location]:
    """The ``CALL``s of the program named under the cursor in the workspace (and its ``.PROGRAM`` line when the
    client asks for the declaration too)."""
    found = _word(ls, params)
    if found is None:
        return []
    target = norm(found[1])
    module = workspace_module(ls)
    out: list[T.Location] = []
    callee = module.programs.get(target)
    if callee is not None and params.context.include_declaration:
        out.append(_location(callee.file, callee.line, 0, 0))
    for prog in module.programs.values():
        for line, st in prog.steps:
            m = _CALL.search(prog.source.get(line, "")) if isinstance(st, CallStmt) and norm(st.name) == target \
                else None
            if m is not None:
                col = prog.indent.get(line, 0) + m.start(1)
                out.append(_location(prog.file, line, col, col + len(m.group(1))))
    return out


@server.feature(T.TEXT_DOCUMENT_DOCUMENT_SYMBOL)
def symbols(ls: LanguageServer, params: T.DocumentSymbolParams) -> list[T.DocumentSymbol]:
    """The document's programs, each from its ``.PROGRAM`` line to its last statement."""
    uri = params.text_document.uri
    module = load_text(ls.workspace.get_text_document(uri).source, _path(uri), Module())
    out = []
    for prog in sorted(module.programs.values(), key=lambda p: p.line):
        last = max([prog.line, *(line for line, _ in prog.steps)])
        head = T.Range(T.Position(prog.line - 1, 0), T.Position(prog.line - 1, 0))
        out.append(T.DocumentSymbol(name=prog.name, kind=T.SymbolKind.Function, selection_range=head,
                                    range=T.Range(head.start, T.Position(last, 0)),
                                    detail=", ".join(p.name for p in prog.params)))
    return out


def _location(file: str, line: int, col: int, end: int) -> T.Location:
    return T.Location(uri=from_fs_path(file) or file, range=T.Range(T.Position(line - 1, col),
                                                                     T.Position(line - 1, end)))


def workspace_module(ls: LanguageServer) -> Module:
    """The programs of the workspace folders' V+ files, with the open documents' current text in place of
    their files' (the file names are full paths, so that a definition can point at its file)."""
    texts: dict[str, str] = {}
    for folder in ls.workspace.folders.values():
        root = Path(_path(folder.uri))
        if root.is_dir():
            for f in sorted(root.rglob("*")):
                if f.suffix.lower() in SUFFIXES and f.is_file():
                    texts[str(f)] = f.read_bytes().decode("latin-1")
    for uri, doc in ls.workspace.text_documents.items():
        texts[_path(uri)] = doc.source
    module = Module()
    for name, text in texts.items():
        load_text(text, name, module)
    return module


def serve() -> None:
    """Serve on stdin/stdout until the client exits."""
    server.start_io()
