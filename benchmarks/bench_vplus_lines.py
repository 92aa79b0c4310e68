"""What recording V+ line coverage costs an emulated server (``AIOADEPT_VPLUS_LINES``, aioadept.vplus.linehits).

Two ``aioadept sim --vplus vplus/... --run rs.main --instant`` child processes run side by side, one recording the
lines it runs (the instrumented form under a line recorder, as every emulated server of ``make test`` runs), one
not (the baseline, in the same run). This process is the client, with one connection to each: after a warm-up
(which also runs every line the benchmark reaches once, so the hooks are dropped as in a long test run), blocks of
``here`` round trips alternate between them, the order swapped every block; the verdict is the median of the
per-block p50 ratios. Goal: recording costs <= 1.5x per round trip.

Usage: ``python benchmarks/bench_vplus_lines.py [--quick] [--messages 500] [--blocks 10]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import statistics
import sys
import tempfile
from pathlib import Path

from bench_vplus import VPLUS_FILES, Conn, _spread, start, stop
from verdicts import verdict

from aioadept.vplus import linehits


async def bench(args: argparse.Namespace, folder: str) -> dict:
    aioadept = str(Path(sys.executable).parent / "aioadept")
    argv = [aioadept, "sim", "--vplus", *VPLUS_FILES, "--run", "rs.main", "--map-port", "1234=0",
            "--map-port", "1235=0", "--instant", "--state-endpoint", "none"]
    names = ["plain", "recording"]
    procs: dict[str, asyncio.subprocess.Process] = {}
    conns: dict[str, Conn] = {}
    rtt: dict[str, list[float]] = {n: [] for n in names}
    try:
        for name in names:
            if name == "recording":
                os.environ[linehits.ENV] = folder
            try:
                procs[name], port = await start(argv)
            finally:
                os.environ.pop(linehits.ENV, None)
            conns[name] = await Conn.open(port)
        for name in names:
            await conns[name].round_trips(args.warmup)
        for b in range(args.blocks):
            for name in (names if b % 2 == 0 else names[::-1]):
                rtt[name].append(statistics.median(await conns[name].round_trips(args.messages)))
    finally:
        for c in conns.values():
            await c.close()
        for p in procs.values():
            await stop(p)
    hits = linehits.load(folder)
    return {"blocks": args.blocks, "messages_per_block": args.messages,
            "here_p50_us_per_block": {n: _spread([x * 1e6 for x in rtt[n]], 1) for n in names},
            "ratio_per_block": _spread([r / p for r, p in zip(rtt["recording"], rtt["plain"], strict=True)]),
            "lines_recorded": sum(len(v) for v in hits.values())}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--messages", type=int, default=500, help="round trips per server and block")
    p.add_argument("--warmup", type=int, default=300)
    p.add_argument("--blocks", type=int, default=10)
    p.add_argument("--quick", action="store_true", help="a smoke run: fewer messages and blocks")
    args = p.parse_args(argv)
    if args.quick:
        args.messages, args.warmup, args.blocks = 200, 50, 3
    with tempfile.TemporaryDirectory(prefix="vplus-lines-") as folder:
        out = asyncio.run(bench(args, folder))
    plain, rec = (out["here_p50_us_per_block"][n]["median"] for n in ("plain", "recording"))
    ratio = out["ratio_per_block"]["median"]
    print(json.dumps({
        "benchmark": "vplus_lines",
        "python": platform.python_version(),
        "machine": platform.machine(),
        **out,
        "verdicts": [verdict("here round trip p50, vplus/ server recording its lines (AIOADEPT_VPLUS_LINES) vs "
                             "not (median of per-block ratios)", rec, plain, unit="us", ratio=ratio,
                             goal="ratio <= 1.5", passed=ratio <= 1.5)],
    }, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
