"""``aioadept vplus lsp``: the V+ Language Server (stdio), a thin adapter over the language core.

- diagnostics of a document on open, change and save: :func:`aioadept.vplus.check.check`;
- hover on an instruction or function name: its form, a one-line summary and its manual section
  (:func:`aioadept.vplus.registry.hover`);
  on a program name: its ``.PROGRAM`` line and where it is;
- go to definition, find references (programs across the workspace's modules, step labels, variables: a
  program's own or global), document symbols (programs and their labels), workspace symbols (programs and
  ``GLOBAL`` variables) and completion (instructions, functions, the workspace's programs with their argument
  lists, the variables in scope): :mod:`aioadept.vplus.symbols`, over the workspace folders' V+ files with the
  open documents' current text in place of their files'.

Needs the ``lsp`` extra (pygls, lsprotocol).
"""

from __future__ import annotations

import gc
import re
import time
from collections.abc import Iterable
from pathlib import Path

from lsprotocol import types as T
from pygls.lsp.server import LanguageServer
from pygls.uris import from_fs_path, to_fs_path

from aioadept import __version__
from aioadept.vplus import registry
from aioadept.vplus.check import check_document
from aioadept.vplus.symbols import DEFINITION, LABEL, PROGRAM, Occurrence, Workspace, file_symbols

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
        T.PublishDiagnosticsParams(uri=uri, version=doc.version, diagnostics=diagnostics(_path(uri), doc.source,
                                                                       workspace_texts(ls).items())))
    # What is alive now is mostly the parse caches (nodes of every piece of every document): moved out of the
    # cycle collector's reach, a full collection no longer scans them all (it did, as 0.3 to 0.4 s pauses of a
    # request after a change of a 2,500-line document); reference counting still frees what the caches drop.
    # The young generations are collected first, so that recent cyclic garbage is not frozen with them.
    gc.collect(1)
    gc.freeze()


_SEVERITY = {"error": T.DiagnosticSeverity.Error, "warning": T.DiagnosticSeverity.Warning}


def diagnostics(name: str, text: str, others: Iterable[tuple[str, str]] = ()) -> list[T.Diagnostic]:
    """The errors and warnings of one document as LSP diagnostics (0-based ranges at the offending word, the
    problem's code), the workspace's ``others`` loaded with it (their programs and assignments count)."""
    return [T.Diagnostic(range=T.Range(T.Position(p.line - 1, p.column - 1), T.Position(p.line - 1,
                                                                                        p.end_column - 1)),
                         message=p.message, severity=_SEVERITY.get(p.severity, T.DiagnosticSeverity.Error),
                         code=p.code, source="aioadept vplus")
            for p in check_document(name, text, others)]


def word_at(line: str, character: int) -> tuple[str, int] | None:
    """The V+ name (``$MID``, ``rs.poll``) that the 0-based ``character`` of ``line`` is in, and where it starts."""
    for m in _WORD.finditer(line):
        if m.start() <= character <= m.end():
            return m.group(), m.start()
    return None


def _occurrence(ls: LanguageServer, params) -> tuple[Workspace, Occurrence | None]:
    ws = workspace(ls)
    return ws, ws.at(_path(params.text_document.uri), params.position.line + 1, params.position.character + 1)


@server.feature(T.TEXT_DOCUMENT_HOVER)
def hover(ls: LanguageServer, params: T.HoverParams) -> T.Hover | None:
    doc = ls.workspace.get_text_document(params.text_document.uri)
    if params.position.line >= len(doc.lines):
        return None
    line = doc.lines[params.position.line]
    found = word_at(line, params.position.character)
    if found is None:
        return None
    word, start = found
    # the statement's first word is an instruction (MOVE), any other a function (SIG( ... ) ; a name that is
    # both (TIMER, SPEED) is described as what it is where it stands
    first = re.fullmatch(r"\s*(\d+\s+)?", line[:start]) is not None
    text = registry.hover(word, instruction=first) or registry.hover(word, instruction=not first)
    if text is None:
        ws, occ = _occurrence(ls, params)
        if occ is None or occ.kind != PROGRAM:
            return None
        text = "\n".join(_program_line(prog) + f" ({Path(prog.file).name}:{line})"
                         for prog, line, _ in ws.programs() if prog.name == occ.name)
        if not text:
            return None
    return T.Hover(contents=T.MarkupContent(kind=T.MarkupKind.PlainText, value=text))


def _program_line(prog) -> str:
    return f".PROGRAM {prog.name}({', '.join(p.name + ('[]' if p.is_array else '') for p in prog.params)})"


@server.feature(T.TEXT_DOCUMENT_COMPLETION)
def completion(ls: LanguageServer, params: T.CompletionParams) -> T.CompletionList:
    """Instructions, functions, the workspace's programs (the detail is the ``.PROGRAM`` line, the label's
    detail the argument list) and the variables in scope at the cursor (the program's own first)."""
    items = [T.CompletionItem(label=name, kind=T.CompletionItemKind.Keyword, detail=registry.describe(
        name, instruction=True)) for name in registry.INSTRUCTIONS]
    items += [T.CompletionItem(label=name, kind=T.CompletionItemKind.Function, detail=registry.describe(name))
              for name in registry.FUNCTIONS if name not in registry.INSTRUCTIONS]
    ws = workspace(ls)
    seen: set[str] = set()
    for prog, _, _ in ws.programs():
        if prog.name not in seen:
            seen.add(prog.name)
            head = _program_line(prog)
            items.append(T.CompletionItem(
                label=prog.name, kind=T.CompletionItemKind.Module, detail=f"{head} ({Path(prog.file).name})",
                label_details=T.CompletionItemLabelDetails(detail=head[len(".PROGRAM ") + len(prog.name):])))
    own, glob = ws.in_scope(_path(params.text_document.uri), params.position.line + 1)
    items += [T.CompletionItem(label=name, kind=T.CompletionItemKind.Variable, detail="local", sort_text="0" + name)
              for name in own]
    items += [T.CompletionItem(label=name, kind=T.CompletionItemKind.Variable, detail="global", sort_text="1" + name)
              for name in glob]
    return T.CompletionList(is_incomplete=False, items=items)


@server.feature(T.TEXT_DOCUMENT_DEFINITION)
def definition(ls: LanguageServer, params: T.DefinitionParams) -> list[T.Location] | None:
    """Where the program, label or variable under the cursor is defined (a global that no ``GLOBAL`` declares:
    the statements that assign it)."""
    ws, occ = _occurrence(ls, params)
    if occ is None:
        return None
    return [_location(o) for o in ws.definitions(occ)] or None


@server.feature(T.TEXT_DOCUMENT_REFERENCES)
def references(ls: LanguageServer, params: T.ReferenceParams) -> list[T.Location]:
    """Every use in the workspace of the program, label or variable under the cursor (and its definitions when
    the client asks for the declaration too)."""
    ws, occ = _occurrence(ls, params)
    if occ is None:
        return []
    return [_location(o) for o in ws.references(occ, declaration=params.context.include_declaration)]


@server.feature(T.TEXT_DOCUMENT_DOCUMENT_SYMBOL)
def symbols(ls: LanguageServer, params: T.DocumentSymbolParams) -> list[T.DocumentSymbol]:
    """The document's programs, each from its ``.PROGRAM`` line to its ``.END``, with its labels inside."""
    uri = params.text_document.uri
    fs = file_symbols(_path(uri), ls.workspace.get_text_document(uri).source)
    names: dict[int, Occurrence] = {}
    labels: dict[int, list[T.DocumentSymbol]] = {}
    for o in fs.occurrences:
        if o.role == DEFINITION and o.kind == PROGRAM:
            names[o.line] = o
        elif o.role == DEFINITION and o.kind == LABEL:      # a label's scope is its program's .PROGRAM line
            labels.setdefault(o.scope, []).append(T.DocumentSymbol(name=o.name, kind=T.SymbolKind.Key,
                                                                   range=_range(o), selection_range=_range(o)))
    out = []
    for prog, start, end in fs.programs:
        name = names.get(start)
        head = _range(name) if name else T.Range(T.Position(start - 1, 0), T.Position(start - 1, 0))
        out.append(T.DocumentSymbol(name=prog.name, kind=T.SymbolKind.Function, selection_range=head,
                                    range=T.Range(T.Position(start - 1, 0), T.Position(end - 1, 4)),
                                    detail=", ".join(p.name for p in prog.params), children=labels.get(start, [])))
    return out


@server.feature(T.WORKSPACE_SYMBOL)
def workspace_symbols(ls: LanguageServer, params: T.WorkspaceSymbolParams) -> list[T.SymbolInformation]:
    """The workspace's programs and ``GLOBAL`` variables whose name holds the query."""
    return [T.SymbolInformation(name=o.name, location=_location(o), container_name=Path(o.file).name,
                                kind=T.SymbolKind.Function if o.kind == PROGRAM else T.SymbolKind.Variable)
            for o in workspace(ls).symbols(params.query)]


def _range(o: Occurrence) -> T.Range:
    return T.Range(T.Position(o.line - 1, o.col - 1), T.Position(o.line - 1, o.end - 1))


def _location(o: Occurrence) -> T.Location:
    return T.Location(uri=from_fs_path(o.file) or o.file, range=_range(o))


_DISK: dict[str, tuple[float, str]] = {}
"""The workspace folders' V+ files by path: (modification time, text), read again only when it changed."""


def _read(path: Path) -> str:
    mtime = path.stat().st_mtime
    got = _DISK.get(str(path))
    if got is None or got[0] != mtime:
        got = _DISK[str(path)] = (mtime, path.read_bytes().decode("latin-1"))
    return got[1]


_LISTED: dict[Path, tuple[float, list[Path]]] = {}
LISTING_TTL = 2.0
"""Seconds a workspace folder's list of V+ files is kept: every request needs it, and walking a large folder
on each would be felt while typing; a file added is seen within this time."""


def _listing(root: Path) -> list[Path]:
    got = _LISTED.get(root)
    if got is None or time.monotonic() - got[0] > LISTING_TTL:
        files = sorted(f for f in root.rglob("*") if f.suffix.lower() in SUFFIXES and f.is_file()) \
            if root.is_dir() else []
        got = _LISTED[root] = (time.monotonic(), files)
    return got[1]


def workspace(ls: LanguageServer) -> Workspace:
    """The workspace folders' V+ files, with the open documents' current text in place of their files' (the
    file names are full paths, so that a definition can point at its file)."""
    return Workspace(workspace_texts(ls).items())


def workspace_texts(ls: LanguageServer) -> dict[str, str]:
    """The texts of :func:`workspace`, by full path."""
    texts: dict[str, str] = {}
    for folder in ls.workspace.folders.values():
        for f in _listing(Path(_path(folder.uri))):
            try:
                texts[str(f)] = _read(f)
            except OSError:            # deleted since it was listed
                continue
    for uri, doc in ls.workspace.text_documents.items():
        texts[_path(uri)] = doc.source
    return texts


def serve() -> None:
    """Serve on stdin/stdout until the client exits."""
    server.start_io()
