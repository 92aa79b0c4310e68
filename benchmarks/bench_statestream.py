"""The V+ server's state stream (vplus/rsstate.V2) through the emulator: its rate, and what it costs the acks.

Two copies of the shipped V+ server run side by side on the emulator (child processes of ``aioadept sim --vplus``):
the **baseline** without the stream, the **streaming** one with ``rs.stream = TRUE`` at ``--rate`` samples/s and
``aioadept state`` relaying it onto ``robot.state``, where this process subscribes (the whole path a live view
sees). Measurement blocks alternate between the two servers (the order swapped every block), as in bench_vplus.py:

- **ack latency**: round trips of ``set_speed:100`` (queued, run by the executor task, acked through the reader)
  and of ``here`` (answered by the reader itself), one after another. Goal: p50 of the streaming server <= 1.10x
  the baseline's (the median of per-block ratios; the issue's "acks delayed by no more than 10 %").
- **rate**: the ``robot.state`` messages the relay published during the blocks, per second of the server's own
  clock (first to last sample). Goal: >= 100 Hz at ``--rate 100``, judged as >= 99.5 Hz (a short run's count
  over its span); the baseline is the configured rate.

Prints one JSON object. Usage: ``python benchmarks/bench_statestream.py [--quick] [--messages 2000] [--blocks 6]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import platform
import statistics
import sys
import tempfile
import time
from itertools import pairwise
from pathlib import Path

from bench_vplus import Conn, start, stop
from verdicts import verdict

ROOT = Path(__file__).resolve().parents[1]
VPLUS = ROOT / "vplus"


def stream_config(folder: Path, rate: int) -> Path:
    cfg = (VPLUS / "rsconfig.V2").read_text()
    cfg = cfg.replace("rs.stream = FALSE", "rs.stream = TRUE").replace("rs.strate = 100", f"rs.strate = {rate}")
    path = folder / "rsconfig.V2"
    path.write_text(cfg)
    return path


async def executor_trips(c: Conn, n: int) -> list[float]:
    """``n`` ``set_speed:100`` round trips (through the command ring and the executor task)."""
    loop = asyncio.get_running_loop()
    out = []
    for _ in range(n):
        mid = c._mid()
        t0 = loop.time()
        c.writer.write(mid + b":set_speed:100\r\n")
        line = await c.reader.readuntil(b"\n")
        out.append(loop.time() - t0)
        if not line.startswith(mid + b":done"):
            raise RuntimeError(f"unexpected ack: {line!r}")
    return out


async def bench(args: argparse.Namespace) -> dict:
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.pubsub import Subscriber

    aioadept = str(Path(sys.executable).parent / "aioadept")
    base = [str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(VPLUS / "rsconfig.V2")]
    tmp = Path(tempfile.mkdtemp(prefix="bench_statestream_"))
    with __import__("socket").socket() as s:
        s.bind(("127.0.0.1", 0))
        sport = s.getsockname()[1]
    streaming = [str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(stream_config(tmp, args.rate)),
                 str(VPLUS / "rsstate.V2")]
    common = ["--run", "rs.main", "--map-port", "1234=0", "--map-port", "1235=0", "--state-endpoint", "none"]
    procs: dict[str, asyncio.subprocess.Process] = {}
    conns: dict[str, Conn] = {}
    names = ["baseline", "streaming"]
    lat: dict[str, dict[str, list[float]]] = {n: {"exec": [], "here": []} for n in names}   # per-block p50 (s)
    avg: dict[str, dict[str, list[float]]] = {n: {"exec": [], "here": []} for n in names}   # per-block mean (s)
    samples: list[RobotState] = []
    relay = None
    try:
        procs["baseline"], port = await start([aioadept, "sim", "--vplus", *base, *common])
        conns["baseline"] = await Conn.open(port)
        procs["streaming"], port = await start([aioadept, "sim", "--vplus", *streaming, *common,
                                                "--map-port", f"1236={sport}"])
        conns["streaming"] = await Conn.open(port)
        relay = await asyncio.create_subprocess_exec(
            aioadept, "state", "--robot", f"127.0.0.1:{sport}", "--state-endpoint", "tcp://127.0.0.1:0",
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.DEVNULL)
        assert relay.stdout is not None
        ready = (await asyncio.wait_for(relay.stdout.readline(), 30)).decode()
        endpoint = dict(f.split("=", 1) for f in ready.split()[1:])["state"]
        async with Subscriber(endpoint, topics=[ROBOT_STATE_TOPIC]) as sub:
            await asyncio.wait_for(sub.recv(), 15)             # the relay is connected and publishing

            async def collect() -> None:
                while True:
                    samples.append(RobotState.from_bytes((await sub.recv())[1]))

            for name in names:                                 # warm-up: not measured
                await executor_trips(conns[name], args.warmup)
                await conns[name].round_trips(args.warmup)
            collector = asyncio.ensure_future(collect())
            t0 = time.monotonic()
            try:
                for b in range(args.blocks):
                    order = names if b % 2 == 0 else names[::-1]
                    for name in order:
                        xs = await executor_trips(conns[name], args.messages)
                        lat[name]["exec"].append(statistics.median(xs))
                        avg[name]["exec"].append(statistics.fmean(xs))
                    for name in order:
                        xs = await conns[name].round_trips(args.messages)
                        lat[name]["here"].append(statistics.median(xs))
                        avg[name]["here"].append(statistics.fmean(xs))
            finally:
                wall = time.monotonic() - t0
                collector.cancel()
                await asyncio.gather(collector, return_exceptions=True)
    finally:
        for c in conns.values():
            await c.close()
        if relay is not None and relay.returncode is None:
            relay.terminate()
            await relay.wait()
        for p in procs.values():
            await stop(p)
    span = samples[-1].t_s - samples[0].t_s if len(samples) > 1 else 0.0
    gaps = sorted(b.t_s - a.t_s for a, b in pairwise(samples))
    out: dict = {"blocks": args.blocks, "messages_per_block": args.messages, "rate_configured_hz": args.rate,
                 "samples": len(samples), "samples_span_s": round(span, 3), "wall_s": round(wall, 3),
                 "rate_hz": round((len(samples) - 1) / span, 1) if span > 0 else None,
                 "gap_ms": {"p50": round(gaps[len(gaps) // 2] * 1e3, 1), "max": round(gaps[-1] * 1e3, 1)}
                 if gaps else None}
    for kind in ("exec", "here"):
        out[kind] = {n: {"p50_us_per_block": [round(x * 1e6, 1) for x in lat[n][kind]],
                         "mean_us_per_block": [round(x * 1e6, 1) for x in avg[n][kind]]} for n in names}
        for key, data in (("ratio_per_block", lat), ("mean_ratio_per_block", avg)):
            ratios = [s / b for s, b in zip(data["streaming"][kind], data["baseline"][kind], strict=True)]
            out[kind][key] = {"median": round(statistics.median(ratios), 3),
                              "min": round(min(ratios), 3), "max": round(max(ratios), 3)}
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rate", type=int, default=100, help="rs.strate of the streaming server (samples/s)")
    p.add_argument("--messages", type=int, default=2000, help="round trips per server, kind and block")
    p.add_argument("--warmup", type=int, default=100)
    p.add_argument("--blocks", type=int, default=6, help="measurement blocks, alternating between the servers")
    p.add_argument("--quick", action="store_true", help="a smoke run: fewer messages and blocks")
    args = p.parse_args(argv)
    if args.quick:
        args.messages, args.warmup, args.blocks = 400, 50, 2
    r = asyncio.run(bench(args))
    verdicts = []

    def med(kind: str, n: str, key: str = "p50_us_per_block") -> float:
        return statistics.median(r[kind][n][key])

    for kind, what in (("exec", "set_speed (executor) ack p50"), ("here", "here (reader) ack p50")):
        ratio = r[kind]["ratio_per_block"]["median"]
        verdicts.append(verdict(f"{what}, V+ server streaming state at {args.rate} Hz vs not streaming (median of "
                                f"per-block ratios)", med(kind, "streaming"), med(kind, "baseline"), unit="us",
                                ratio=ratio, goal="ratio <= 1.10", passed=ratio <= 1.10))
        verdicts.append(verdict(f"{what.replace('p50', 'mean')}, streaming vs not (median of per-block ratios)",
                                med(kind, "streaming", "mean_us_per_block"), med(kind, "baseline", "mean_us_per_block"),
                                unit="us",
                                ratio=r[kind]["mean_ratio_per_block"]["median"]))
    rate = r["rate_hz"]
    verdicts.append(verdict("robot.state rate from the V+ stream through the emulator and aioadept state", rate,
                            float(args.rate), unit="Hz", goal=">= 99.5 Hz (100 Hz, 0.5 % for the span's ends)",
                            passed=rate is not None and rate >= 99.5))
    print(json.dumps({"benchmark": "statestream", "python": platform.python_version(),
                      "machine": platform.machine(), **r, "verdicts": verdicts}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
