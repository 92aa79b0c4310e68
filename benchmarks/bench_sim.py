"""Ack round trip of ``aioadept sim`` with 1, 10 and 50 concurrent clients, vs a raw asyncio line-echo server.

Both servers run as child processes on 127.0.0.1 (port 0, real port read from their ``READY`` line, no sleep):

- **sim**: ``aioadept sim --instant --state-endpoint none``; every request is ``ID:here`` (one skill through the
  framer, parser, serial executor, forward kinematics and ack encoder).
- **baseline**: a bare asyncio server that splits lines and answers each with a fixed ack line of the same length,
  so the ratio is what the simulated controller costs on top of asyncio streams.

Each client runs its own round trips one after another (write a line, read its ack); the clients run
concurrently. Latency is the client's loop-clock time from write to read. Prints one JSON object.

Usage: ``python benchmarks/bench_sim.py [--messages 3000] [--clients 1,10,50] [--rounds 2]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import platform
import statistics
import sys
from pathlib import Path

from verdicts import verdict

ECHO_SERVER = r"""
import asyncio, sys
ACK = sys.argv[1].encode() + b"\r\n"
async def serve(reader, writer):
    buf = b""
    while True:
        data = await reader.read(65536)
        if not data:
            break
        buf += data
        *lines, buf = buf.split(b"\n")
        for line in lines:
            if line.strip():
                writer.write(line[:8] + ACK)
        await writer.drain()
    writer.close()
async def main():
    server = await asyncio.start_server(serve, "127.0.0.1", 0)
    print("READY host=127.0.0.1 port=%d" % server.sockets[0].getsockname()[1], flush=True)
    async with server:
        await server.serve_forever()
asyncio.run(main())
"""

# Same length as the sim's ack to "here" at home (minus the 8-character ID the server copies from the request).
HERE_ACK_TAIL = ":done:0.000,0.000:480.000,0.000,710.000,0.000,180.000,0.000:0.000,-90.000,180.000,0.000,90.000,0.000"


async def start(argv: list[str]) -> tuple[asyncio.subprocess.Process, int]:
    proc = await asyncio.create_subprocess_exec(*argv, stdout=asyncio.subprocess.PIPE,
                                                stderr=asyncio.subprocess.DEVNULL)
    assert proc.stdout is not None
    line = (await proc.stdout.readline()).decode()
    if not line.startswith("READY"):
        proc.kill()
        raise RuntimeError(f"server did not start: {line!r}")
    fields = dict(f.split("=", 1) for f in line.split()[1:])
    return proc, int(fields["port"])


async def stop(proc: asyncio.subprocess.Process) -> None:
    if proc.returncode is None:
        proc.terminate()
        await proc.wait()


async def client(port: int, n: int, index: int, out: list[float]) -> None:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    loop = asyncio.get_running_loop()
    try:
        for i in range(n):
            mid = b"%02x%06x" % (index % 256, i)
            t0 = loop.time()
            writer.write(mid + b":here\r\n")
            line = await reader.readuntil(b"\r\n")
            out.append(loop.time() - t0)
            if not line.startswith(mid):
                raise RuntimeError(f"ack for another message: {line!r}")
    finally:
        writer.close()
        await writer.wait_closed()


async def measure(port: int, clients: int, messages: int, warmup: int) -> dict[str, float]:
    per_client = max(1, messages // clients)
    await asyncio.gather(*(client(port, max(1, warmup // clients), i, []) for i in range(clients)))
    samples: list[float] = []
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    await asyncio.gather(*(client(port, per_client, i, samples) for i in range(clients)))
    wall = loop.time() - t0
    samples.sort()
    return {
        "n": len(samples),
        "p50_us": round(samples[len(samples) // 2] * 1e6, 1),
        "p99_us": round(samples[min(len(samples) - 1, int(len(samples) * 0.99))] * 1e6, 1),
        "mean_us": round(statistics.fmean(samples) * 1e6, 1),
        "acks_per_s": round(len(samples) / wall, 1),
    }


async def main_async(args: argparse.Namespace) -> dict:
    aioadept = str(Path(sys.executable).parent / "aioadept")
    sim_argv = [aioadept, "sim", "--port", "0", "--instant", "--state-endpoint", "none",
                "--max-clients", str(max(args.clients) + 1)]
    echo_argv = [sys.executable, "-c", ECHO_SERVER, HERE_ACK_TAIL]
    cases = []
    for n_clients in args.clients:
        best: dict[str, dict] = {}
        for _ in range(args.rounds):
            for name, argv in (("baseline", echo_argv), ("sim", sim_argv)):
                proc, port = await start(argv)
                try:
                    r = await measure(port, n_clients, args.messages, args.warmup)
                finally:
                    await stop(proc)
                # Keep each side's best round: the least disturbed by the rest of the machine.
                if name not in best or r["p50_us"] < best[name]["p50_us"]:
                    best[name] = r
        cases.append({
            "clients": n_clients,
            "sim": best["sim"],
            "baseline_echo": best["baseline"],
            "ratio_p50": round(best["sim"]["p50_us"] / best["baseline"]["p50_us"], 2),
            "ratio_p99": round(best["sim"]["p99_us"] / best["baseline"]["p99_us"], 2),
        })
    return {
        "benchmark": "sim_ack_round_trip",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "messages_per_case": args.messages,
        "rounds": args.rounds,
        "cases": cases,
        "verdicts": [verdict(f"here round trip p50, {c['clients']} client(s), sim vs line echo", c["sim"]["p50_us"],
                             c["baseline_echo"]["p50_us"], unit="us") for c in cases],
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--messages", type=int, default=3000, help="measured round trips per case (split over clients)")
    p.add_argument("--warmup", type=int, default=300)
    p.add_argument("--clients", type=lambda s: [int(v) for v in s.split(",")], default=[1, 10, 50])
    p.add_argument("--rounds", type=int, default=2, help="repeat each case, keep each side's best p50")
    args = p.parse_args(argv)
    print(json.dumps(asyncio.run(main_async(args)), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
