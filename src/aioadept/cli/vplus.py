"""``aioadept vplus check|lsp``: V+ source tools over the language core (:mod:`aioadept.vplus.check`).

``check FILE|DIR ...`` prints every problem of the files (a folder: its ``.V2``/``.pg`` files, recursively),
loaded together, one line each (``file:line:col: error|warning: message [code]``, or GitHub Actions annotations
with ``--format github``; ``--format json``: one JSON array; ``--format sarif``: a SARIF 2.1.0 log); exit status 1
when there is an error (with ``--strict`` a warning too), 0 otherwise, 2 for a usage mistake.
``lsp`` serves the Language Server Protocol on stdin/stdout (:mod:`aioadept.vplus.lsp`, the ``lsp`` extra).
``dap`` serves the Debug Adapter Protocol on stdin/stdout or ``--listen 127.0.0.1:PORT`` (:mod:`aioadept.vplus.dap`).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from aioadept.cli.options import DefaultsHelpFormatter

SUFFIXES = (".v2", ".pg")
"""The files a folder argument contributes (case-insensitive)."""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="aioadept vplus", description="V+ source tools (docs/vplus.md)",
                                formatter_class=DefaultsHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    c = sub.add_parser("check", help="report every problem of V+ files without running them",
                       formatter_class=DefaultsHelpFormatter)
    c.add_argument("paths", nargs="+", metavar="FILE|DIR", help="V+ files, or folders of them, loaded together")
    c.add_argument("--format", choices=("text", "github", "json", "sarif"), default="text",
                   help="text: file:line:col: error|warning: message [code]; github: GitHub Actions annotations; "
                        "json: one array of {file, line, column, end_column, severity, code, message}; sarif: a "
                        "SARIF 2.1.0 log (code scanning)")
    c.add_argument("--strict", action="store_true", help="exit 1 on a warning too (else only on an error)")
    sub.add_parser("lsp", help="serve the V+ Language Server Protocol on stdin/stdout (editors)")
    d = sub.add_parser("dap", help="serve the V+ Debug Adapter Protocol on stdin/stdout (debuggers; docs/vplus.md, "
                                   "Debugging)", formatter_class=DefaultsHelpFormatter)
    d.add_argument("--listen", metavar="127.0.0.1:PORT", default=None,
                   help="serve one session on this loopback TCP address instead of stdin/stdout")
    m = sub.add_parser("monitor", help="the V+ monitor (LOAD, EXECUTE, BPT, STATUS, ...) over the emulator with the "
                                       "simulated arm (docs/vplus.md, Debugging)", formatter_class=DefaultsHelpFormatter)
    m.add_argument("files", nargs="*", metavar="FILE", help="V+ files to LOAD first")
    m.add_argument("--time-scale", type=float, default=1.0, dest="time_scale", help="the sim's time scale")
    m.add_argument("--connect", metavar="127.0.0.1:PORT", default=None,
                   help="the monitor of a running aioadept sim --vplus ... --debug-port PORT instead")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "lsp":
        from aioadept.vplus.lsp import serve

        serve()
        return 0
    if args.command == "dap":
        return dap_main(args.listen)
    if args.command == "monitor":
        import asyncio

        from aioadept.vplus.monitor import connect, serve

        if args.connect is None:
            return asyncio.run(serve(args.files, args.time_scale))
        if args.files:
            print("aioadept vplus monitor: --connect takes no FILE (the sim has loaded its own)", file=sys.stderr)
            return 2
        try:
            from aioadept.vplus.dap import parse_listen

            return asyncio.run(connect(*parse_listen(args.connect, "--connect")))
        except (ValueError, OSError) as exc:
            what = exc if isinstance(exc, ValueError) else f"--connect {args.connect}: {exc.strerror or exc}"
            print(f"aioadept vplus monitor: {what}", file=sys.stderr)
            return 2
    return check_main(args.paths, args.format, args.strict)


def dap_main(listen: str | None) -> int:
    import asyncio

    from aioadept.vplus import dap

    if listen is None:
        asyncio.run(dap.serve_stdio())
        return 0
    try:
        host, port = dap.parse_listen(listen)
    except ValueError as exc:
        print(f"aioadept vplus dap: {exc}", file=sys.stderr)
        return 2
    try:
        asyncio.run(dap.serve_tcp(host, port, lambda p: print(f"LISTENING {host}:{p}", flush=True)))
    except OSError as exc:
        print(f"aioadept vplus dap: --listen {listen}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    return 0


def check_main(paths: list[str], fmt: str, strict: bool = False) -> int:
    from aioadept.vplus.check import check, sarif

    try:
        files = source_files(paths)
    except ValueError as exc:
        print(f"aioadept vplus check: {exc}", file=sys.stderr)
        return 2
    problems = check(((str(f), f.read_bytes().decode("latin-1")) for f in files), warnings=True)
    if fmt == "json":
        print(json.dumps([{f: getattr(p, f) for f in ("file", "line", "column", "end_column", "severity", "code",
                                                      "message")} for p in problems], indent=1))
    elif fmt == "sarif":
        print(json.dumps(sarif(problems), indent=1))
    else:
        for p in problems:
            print(github_annotation(p) if fmt == "github" else str(p))
    return 1 if any(p.severity == "error" or strict for p in problems) else 0


def source_files(paths: list[str]) -> list[Path]:
    """The files named, and a folder's V+ files in name order; ``ValueError`` naming a path that is neither."""
    out: list[Path] = []
    for raw in paths:
        path = Path(raw)
        if path.is_dir():
            found = sorted(f for f in path.rglob("*") if f.is_file() and f.suffix.lower() in SUFFIXES)
            if not found:
                raise ValueError(f"{raw}: no V+ files ({', '.join(SUFFIXES)}) in this folder")
            out.extend(found)
        elif path.is_file():
            out.append(path)
        else:
            raise ValueError(f"{raw}: no such file")
    return out


def github_annotation(p) -> str:
    """``::error file=F,line=L,col=C,endColumn=E,title=CODE::message [CODE]`` (``::warning`` for a warning),
    escaped as GitHub Actions' workflow commands require (``%``, CR, LF everywhere; ``:`` and ``,`` in a property
    too)."""
    def data(s: str) -> str:
        return s.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")

    def prop(s: str) -> str:
        return data(s).replace(":", "%3A").replace(",", "%2C")

    return (f"::{p.severity} file={prop(p.file)},line={p.line},col={p.column},endColumn={p.end_column},"
            f"title={prop(p.code)}::{data(p.message)} [{data(p.code)}]")
