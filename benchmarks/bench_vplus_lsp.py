"""V+ language server latency, over the protocol: ``aioadept vplus lsp`` as a real process on stdin/stdout,
driven by a minimal JSON-RPC client, with a ~2,000-line module open.

The four ``vplus/*.V2`` files pasted into one document (2,388 lines) in a workspace folder, opened once; then each
round a comment is typed at the end of a line in the middle (a full-text ``didChange``, as VS Code sends with
full sync) and the time until the server publishes that version's diagnostics is measured, then go to definition
of a ``CALL`` target, its references, hover on an instruction, completion and document symbols (each right after
a change, so the server works on the new text). The baseline, alternately in the same run: the same work in this
process without the protocol (:func:`aioadept.vplus.lsp.diagnostics`, and the language core's workspace and
definition for the requests). Goal: diagnostics within 100 ms of a change for a 2,000-line module, p95.

Usage: ``python benchmarks/bench_vplus_lsp.py [--rounds 20]``; prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from verdicts import verdict

from aioadept.vplus.lsp import diagnostics
from aioadept.vplus.symbols import Workspace

ROOT = Path(__file__).resolve().parents[1]


def p95(xs: list[float]) -> float:
    return sorted(xs)[max(0, round(0.95 * len(xs)) - 1)]


class Client:
    """Just enough of an LSP client: Content-Length framing over the server's pipes, requests by id."""

    def __init__(self, cwd: Path) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "aioadept.cli", "vplus", "lsp"], cwd=cwd,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        self.next_id = 0

    def send(self, msg: dict) -> None:
        body = json.dumps(msg).encode()
        self.proc.stdin.write(b"Content-Length: %d\r\n\r\n" % len(body) + body)
        self.proc.stdin.flush()

    def read(self) -> dict:
        length = 0
        while (line := self.proc.stdout.readline().strip()):
            if line.lower().startswith(b"content-length:"):
                length = int(line.split(b":")[1])
        return json.loads(self.proc.stdout.read(length))

    def notify(self, method: str, params: dict) -> None:
        self.send({"jsonrpc": "2.0", "method": method, "params": params})

    def request(self, method: str, params: dict):
        self.next_id += 1
        self.send({"jsonrpc": "2.0", "id": self.next_id, "method": method, "params": params})
        while True:
            msg = self.read()
            if msg.get("id") == self.next_id:
                assert "error" not in msg, msg
                return msg["result"]

    def diagnostics(self, version: int) -> list:
        while True:
            msg = self.read()
            if msg.get("method") == "textDocument/publishDiagnostics" and msg["params"].get("version") == version:
                return msg["params"]["diagnostics"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=20)
    args = ap.parse_args()
    text = "\n".join(p.read_text("latin-1") for p in sorted((ROOT / "vplus").glob("*.V2")))
    lines = text.split("\n")
    middle = len(lines) // 2
    # a CALL near the middle: where definition and references are asked
    row = next(i for i in range(middle, len(lines)) if lines[i].strip().upper().startswith("CALL "))
    col = lines[row].upper().index("CALL ") + 6
    names = ["diagnostics", "definition", "references", "hover", "completion", "documentSymbol"]
    lsp: dict[str, list[float]] = {n: [] for n in names}
    core: dict[str, list[float]] = {"diagnostics": [], "definition": []}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        doc = folder / "bench.V2"
        doc.write_text(text, "latin-1")
        uri = doc.as_uri()
        client = Client(folder)
        client.request("initialize", {"processId": None, "capabilities": {},
                                      "workspaceFolders": [{"uri": folder.as_uri(), "name": "bench"}]})
        client.notify("initialized", {})
        client.notify("textDocument/didOpen", {"textDocument": {"uri": uri, "languageId": "vplus", "version": 1,
                                                                "text": text}})
        assert client.diagnostics(1) == []
        at = {"textDocument": {"uri": uri}, "position": {"line": row, "character": col}}
        requests = {
            "definition": ("textDocument/definition", at),
            "references": ("textDocument/references", {**at, "context": {"includeDeclaration": True}}),
            "hover": ("textDocument/hover", {**at, "position": {"line": row, "character": col - 3}}),
            "completion": ("textDocument/completion", at),
            "documentSymbol": ("textDocument/documentSymbol", {"textDocument": {"uri": uri}}),
        }
        version = 1
        for k in range(-1, args.rounds):          # round -1 warms up (imports, first use of each request)
            for name in names:
                version += 1
                edited = "\n".join(lines[:middle] + [f"{lines[middle]} ; edit {version}"] + lines[middle + 1:])
                t0 = time.perf_counter()
                client.notify("textDocument/didChange", {"textDocument": {"uri": uri, "version": version},
                                                         "contentChanges": [{"text": edited}]})
                assert client.diagnostics(version) == []
                t1 = time.perf_counter()
                if name != "diagnostics":
                    assert client.request(*requests[name])
                t2 = time.perf_counter()
                if k >= 0:
                    lsp[name].append((t1 - t0 if name == "diagnostics" else t2 - t1) * 1e3)
            # the core in this process: the same texts, the same work
            edited = "\n".join(lines[:middle] + [f"{lines[middle]} ; core {k}"] + lines[middle + 1:])
            t0 = time.perf_counter()
            assert diagnostics(str(doc), edited) == []
            t1 = time.perf_counter()
            ws = Workspace([(str(doc), edited)])
            assert ws.definitions(ws.at(str(doc), row + 1, col + 1))
            t2 = time.perf_counter()
            if k >= 0:
                core["diagnostics"].append((t1 - t0) * 1e3)
                core["definition"].append((t2 - t1) * 1e3)
        client.request("shutdown", {})
        client.notify("exit", {})
        client.proc.wait(timeout=10)

    def stats(xs: list[float]) -> dict:
        return {"p50": statistics.median(xs), "p95": p95(xs), "max": max(xs)}

    n = len(lines)
    print(json.dumps({
        "benchmark": "bench_vplus_lsp", "python": platform.python_version(), "lines": n, "rounds": args.rounds,
        **{f"lsp_{name}_ms": stats(xs) for name, xs in lsp.items()},
        **{f"core_{name}_ms": stats(xs) for name, xs in core.items()},
        "verdicts": [
            verdict(f"aioadept vplus lsp: didChange of a {n}-line module to its publishDiagnostics, p95, vs the "
                    "diagnostics computed in-process", p95(lsp["diagnostics"]), p95(core["diagnostics"]), unit="ms",
                    goal="figure <= 100 ms", passed=p95(lsp["diagnostics"]) <= 100),
            *(verdict(f"aioadept vplus lsp: {name} right after a change of a {n}-line module, p95, vs the "
                      "workspace and a definition computed in-process", p95(lsp[name]), p95(core["definition"]),
                      unit="ms") for name in names[1:])],
    }, indent=2))


if __name__ == "__main__":
    main()
