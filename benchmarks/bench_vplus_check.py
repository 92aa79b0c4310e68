"""V+ diagnostics latency: what the language server computes after each change of a ~2,000-line module.

The four ``vplus/*.V2`` files pasted into one document (2,388 lines), checked once, then each round: a comment
typed at the end of a line in the middle (typing), lines inserted on top (every program moves, each round to new
lines), and the same text as a new document (nothing of it checked before). The figures are
:func:`aioadept.vplus.lsp.diagnostics` of the text (what ``aioadept vplus lsp`` publishes after a change, minus
the JSON-RPC); the baseline is loading the text into the emulator (``Emulator.from_source``: how a V+ programmer
found problems before, one load), measured alternately in the same run. Goal (issue 32): diagnostics within
100 ms of a change for a 2,000-line module, p95.

Usage: ``python benchmarks/bench_vplus_check.py [--rounds 30]``; prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from pathlib import Path

from verdicts import verdict

from aioadept.vplus import Emulator
from aioadept.vplus.lsp import diagnostics

ROOT = Path(__file__).resolve().parents[1]


def p95(xs: list[float]) -> float:
    return sorted(xs)[max(0, round(0.95 * len(xs)) - 1)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=30)
    args = ap.parse_args()
    text = "\n".join(p.read_text("latin-1") for p in sorted((ROOT / "vplus").glob("*.V2")))
    lines = text.split("\n")
    middle = len(lines) // 2
    diagnostics("bench.V2", text)          # imports, first use, and the pieces of the text checked once
    typed, inserted, fresh, load = [], [], [], []
    for k in range(args.rounds):
        # typing: one line in the middle changes (its piece is checked again, the others are known)
        one_line = "\n".join(lines[:middle] + [f"{lines[middle]} ; edit {k}"] + lines[middle + 1:])
        # lines inserted on top, one more each round: every program moves to lines it never had
        on_top = f"; edit {k}\n" * (k + 1) + text
        t0 = time.perf_counter()
        found = diagnostics("bench.V2", one_line)
        t1 = time.perf_counter()
        found += diagnostics("bench.V2", on_top)
        t2 = time.perf_counter()
        found += diagnostics(f"new{k}.V2", text)      # a document never seen: every program is checked
        t3 = time.perf_counter()
        Emulator.from_source(f"{text}\n; load {k}\n", filename="bench.V2", robot=False)
        t4 = time.perf_counter()
        assert found == [], found
        typed.append((t1 - t0) * 1e3)
        inserted.append((t2 - t1) * 1e3)
        fresh.append((t3 - t2) * 1e3)
        load.append((t4 - t3) * 1e3)

    def stats(xs: list[float]) -> dict:
        return {"p50": statistics.median(xs), "p95": p95(xs), "max": max(xs)}

    n = len(lines)
    print(json.dumps({
        "benchmark": "bench_vplus_check", "python": platform.python_version(), "lines": n, "rounds": args.rounds,
        "diagnostics_ms_one_line_changed": stats(typed), "diagnostics_ms_lines_inserted_on_top": stats(inserted),
        "diagnostics_ms_new_document": stats(fresh),
        "emulator_load_ms": stats(load),
        "verdicts": [
            verdict(f"V+ diagnostics of a {n}-line module after one line changed, p95, vs the emulator loading it",
                    p95(typed), p95(load), unit="ms", goal="figure <= 100 ms", passed=p95(typed) <= 100),
            verdict(f"V+ diagnostics of a {n}-line module after lines inserted on top, p95, vs the emulator "
                    "loading it", p95(inserted), p95(load), unit="ms", goal="figure <= 100 ms",
                    passed=p95(inserted) <= 100),
            verdict(f"V+ diagnostics of a new {n}-line document, p95, vs the emulator loading it", p95(fresh),
                    p95(load), unit="ms", goal="figure <= 100 ms", passed=p95(fresh) <= 100)],
    }, indent=2))

if __name__ == "__main__":
    main()
