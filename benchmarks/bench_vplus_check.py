"""V+ diagnostics latency: what the language server computes after each change of a ~2,000-line module.

The four ``vplus/*.V2`` files pasted into one document (2,388 lines), edited each round (a comment line that
changes, so no cache of parsed text helps): the figure is :func:`aioadept.vplus.lsp.diagnostics` of the edited
text (what ``aioadept vplus lsp`` publishes after a change, minus the JSON-RPC), the baseline is loading the same
edited text into the emulator (``Emulator.from_source``: how a V+ programmer found problems before, one load),
measured alternately in the same run. Goal (issue 32): diagnostics within 100 ms of a change for a 2,000-line
module, p95.

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
    lines = len(text.splitlines())
    diagnostics("bench.V2", text)          # imports and first-use costs outside the figures
    check_ms, load_ms = [], []
    for k in range(args.rounds):
        edited = f"{text}\n; edit {k}\n"
        t0 = time.perf_counter()
        found = diagnostics("bench.V2", edited)
        t1 = time.perf_counter()
        Emulator.from_source(f"{edited}; load\n", filename="bench.V2", robot=False)
        t2 = time.perf_counter()
        assert found == [], found
        check_ms.append((t1 - t0) * 1e3)
        load_ms.append((t2 - t1) * 1e3)
    fig, base = p95(check_ms), p95(load_ms)
    print(json.dumps({
        "benchmark": "bench_vplus_check", "python": platform.python_version(), "lines": lines,
        "rounds": args.rounds,
        "diagnostics_ms": {"p50": statistics.median(check_ms), "p95": fig, "max": max(check_ms)},
        "emulator_load_ms": {"p50": statistics.median(load_ms), "p95": base, "max": max(load_ms)},
        "verdicts": [verdict(f"V+ diagnostics of a {lines}-line module after a change, p95, vs the emulator "
                             "loading it", fig, base, unit="ms", goal="figure <= 100 ms", passed=fig <= 100)],
    }, indent=2))


if __name__ == "__main__":
    main()
