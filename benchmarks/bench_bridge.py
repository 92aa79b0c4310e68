"""The robot bridge: what the extra hop costs, and how fast a stop goes through it under load.

Starts ``aioadept sim`` and ``aioadept bridge`` as child processes on 127.0.0.1; this process is the Zenoh router
(multicast scouting off). Measured in the same run:

- **round trip**: ``here`` through the bridge (:class:`BridgeClient`: Zenoh query -> bridge -> TCP -> sim and
  back) against ``here`` straight to the sim (:class:`RobotClient`), in alternating blocks. No goal stated: the
  ratio of the p50s is reported.
- **stop under flood**: a second application (a child process) keeps ``--flood`` ``here`` queries outstanding
  all the time, queued in the bridge; this process sends ``stop`` (robot at rest, so the ack is immediate) and
  times it to its ``done`` ack. Goal: p95 <= 100 ms. Baseline: the same stop straight to the sim, no flood.
- **stop under a flood of names**: while another application's slow motion holds the writer, a
  child process sends ``--names`` ``here`` queries, each from an application name of its own (raw Zenoh queries,
  as an attacker or a buggy fleet would), then this process sends ``stop`` at once and times it to its ``done``
  ack; ``--name-rounds`` rounds. Baseline, alternating with them: the same stop with the writer held, no flood.
  Goal: p95 <= 100 ms. The bridge's RSS before the first flood round and after each is reported.

Prints one JSON object. Usage: ``python benchmarks/bench_bridge.py [--n 500] [--blocks 4] [--stops 40]
[--names 20000] [--name-rounds 10]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import socket
import statistics
import sys
import textwrap
import time

from verdicts import verdict

FLOOD = textwrap.dedent("""
    import asyncio, sys
    from aioadept.bus import zenoh as zb
    from aioadept.bridge import BridgeClient

    async def main(router, cell, name, n):
        zb.configure(zb.ZenohOptions.client(router))
        async with BridgeClient(cell, name, app="flood") as b:
            count = 0
            async def one():
                nonlocal count
                while True:
                    await b.here()
                    count += 1
            tasks = [asyncio.create_task(one()) for _ in range(int(n))]
            print("FLOODING", flush=True)
            while True:
                await asyncio.sleep(0.25)
                print("COUNT", count, flush=True)
    asyncio.run(main(*sys.argv[1:]))
""")


NAMES = textwrap.dedent("""
    import sys, zenoh
    from aioadept.bus import zenoh as zb
    from aioadept.bridge.wire import cmd_key

    router, cell, name = sys.argv[1:4]
    zb.configure(zb.ZenohOptions.client(router))
    s, key, k = zb.session(), cmd_key(cell, name), 0
    print("READY", flush=True)
    for line in sys.stdin:               # "GO N": N queries, each from an application name of its own
        for _ in range(int(line.split()[1])):
            k += 1
            s.get(key, zenoh.handlers.Callback(lambda rep: None), payload=f"{k:08x}:here\\r\\n".encode(),
                  attachment=f"n{k}".encode(), timeout=60)
        print("SENT", flush=True)
""")


def rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


async def names_flood(args: argparse.Namespace, router: str, cell: str, name: str, via, mover,
                      bridge_pid: int) -> dict:
    """Stops with the writer held by a slow motion: alternately without and right after a flood of names."""
    from aioadept.commands import Break, Joined, MoveRelJoints, SetSpeed

    child = await asyncio.create_subprocess_exec(sys.executable, "-c", NAMES, router, cell, name,
                                                 stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE)
    base: list[float] = []
    flood: list[float] = []
    try:
        if (await asyncio.wait_for(child.stdout.readline(), 30)).strip() != b"READY":
            raise RuntimeError("the names flood did not start")
        rss = [rss_mb(bridge_pid)]
        for k in range(2 * args.name_rounds):
            sign = 1 if k % 4 < 2 else -1
            motion = asyncio.create_task(mover.cmdexec_joined(Joined(SetSpeed(5), MoveRelJoints([sign * 20, 0, 0,
                                                                                                   0, 0, 0]), Break())))
            await asyncio.sleep(0.3)          # the motion holds the writer
            if k % 2:
                child.stdin.write(f"GO {args.names}\n".encode())
                await child.stdin.drain()
                if (await asyncio.wait_for(child.stdout.readline(), 120)).strip() != b"SENT":
                    raise RuntimeError("the names flood stopped")
            (flood if k % 2 else base).extend(await trips(via.stop, 1))
            await asyncio.gather(motion, return_exceptions=True)
            await asyncio.sleep(0.5)          # the refusals and aborts drain before the next round
            if k % 2:
                rss.append(rss_mb(bridge_pid))
    finally:
        child.kill()
        await child.wait()
    return {"base": base, "flood": flood, "rss": rss}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(q * (len(xs) - 1))))]


def summary_ms(xs: list[float]) -> dict:
    return {"n": len(xs), "p50_ms": round(pct(xs, 0.5) * 1e3, 4), "p95_ms": round(pct(xs, 0.95) * 1e3, 4),
            "max_ms": round(max(xs) * 1e3, 4)}


async def trips(call, n: int) -> list[float]:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        await call()
        out.append(time.perf_counter() - t0)
    return out


async def bench(args: argparse.Namespace) -> dict:
    from aioadept.bridge import BridgeClient
    from aioadept.bus import zenoh as zb
    from aioadept.client import RobotClient
    from aioadept.testing.nodes import running_node

    router = f"tcp/127.0.0.1:{free_port()}"
    zb.configure(zb.ZenohOptions.router(router))
    zb.session()
    cell, name = "bench", f"r{os.getpid()}"
    async with running_node("sim", "--port", "0", "--state-endpoint", "none") as sim:
        port = int(sim.ready["port"])
        async with running_node("bridge", "--robot", f"127.0.0.1:{port}", "--stop-port", sim.ready["stop_port"],
                                "--zenoh-connect", router, "--cell", cell,
                                "--name", name, expect_clean_exit=False) as bridge:
            direct = RobotClient("127.0.0.1", port, stop_port=int(sim.ready["stop_port"]))
            via = BridgeClient(cell, name, app="bench")
            mover = BridgeClient(cell, name, app="mover")
            async with direct, via, mover:
                await trips(direct.here, args.warmup)
                await trips(via.here, args.warmup)
                d_all: list[float] = []
                b_all: list[float] = []
                ratios = []
                for k in range(args.blocks):
                    order = [(direct.here, d_all), (via.here, b_all)]
                    if k % 2:
                        order.reverse()
                    block = {}
                    for call, sink in order:
                        xs = await trips(call, args.n)
                        sink.extend(xs)
                        block[id(sink)] = statistics.median(xs)
                    ratios.append(block[id(b_all)] / block[id(d_all)])
                stop_direct = await trips(direct.stop, args.stops)
                flood = await asyncio.create_subprocess_exec(
                    sys.executable, "-c", FLOOD, router, cell, name, str(args.flood),
                    stdout=asyncio.subprocess.PIPE)
                try:
                    line = await asyncio.wait_for(flood.stdout.readline(), 30)
                    if line.strip() != b"FLOODING":
                        raise RuntimeError(f"flood app said {line!r}")
                    counts: list[tuple[float, int]] = []

                    async def read_counts() -> None:
                        while line := await flood.stdout.readline():
                            counts.append((time.perf_counter(), int(line.split()[1])))

                    reader = asyncio.create_task(read_counts())
                    await asyncio.sleep(0.5)
                    stop_flood = []
                    for _ in range(args.stops):
                        stop_flood.extend(await trips(via.stop, 1))
                        await asyncio.sleep(0.02)
                    # The flood's here() queries, to show they were served meanwhile: one of ours waits behind them.
                    t0 = time.perf_counter()
                    await via.here()
                    here_behind_flood_s = time.perf_counter() - t0
                    await asyncio.sleep(0.3)
                    reader.cancel()
                    (t_a, n_a), (t_b, n_b) = counts[0], counts[-1]
                    flood_rate = (n_b - n_a) / (t_b - t_a)
                finally:
                    flood.kill()
                    await flood.wait()
                names = await names_flood(args, router, cell, name, via, mover, bridge.proc.pid)
    zb.close_session()
    rt_ratio = statistics.median(ratios)
    stop_p95 = pct(stop_flood, 0.95)
    return {
        "benchmark": "bench_bridge",
        "python": platform.python_version(), "machine": platform.machine(), "cpus": os.cpu_count(),
        "n_per_block": args.n, "blocks": args.blocks, "flood_outstanding": args.flood,
        "round_trip_direct": summary_ms(d_all), "round_trip_bridge": summary_ms(b_all),
        "round_trip_ratio_per_block": [round(r, 3) for r in ratios],
        "stop_direct_no_flood": summary_ms(stop_direct), "stop_bridge_flood": summary_ms(stop_flood),
        "here_behind_flood_ms": round(here_behind_flood_s * 1e3, 3),
        "flood_queries_per_s": round(flood_rate, 1),
        "names_per_round": args.names, "name_rounds": args.name_rounds,
        "stop_bridge_writer_busy": summary_ms(names["base"]),
        "stop_bridge_names_flood": summary_ms(names["flood"]),
        "bridge_rss_mb_before_and_after_each_names_round": [round(x, 1) for x in names["rss"]],
        "verdicts": [
            verdict("here round trip p50, through the bridge vs RobotClient direct", pct(b_all, 0.5) * 1e3,
                    pct(d_all, 0.5) * 1e3, unit="ms", ratio=rt_ratio),
            verdict("stop p95 through the bridge with another app flooding (vs direct stop, no flood)",
                    stop_p95 * 1e3, pct(stop_direct, 0.95) * 1e3, unit="ms", goal="figure <= 100 ms",
                    passed=stop_p95 <= 0.100),
            verdict(f"stop p95 through the bridge right after {args.names} queries from as many application names, "
                    "writer busy (vs the same stop, writer busy, no flood)", pct(names["flood"], 0.95) * 1e3,
                    pct(names["base"], 0.95) * 1e3, unit="ms", goal="figure <= 100 ms",
                    passed=pct(names["flood"], 0.95) <= 0.100),
        ],
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=500, help="round trips per block and client")
    p.add_argument("--blocks", type=int, default=4)
    p.add_argument("--warmup", type=int, default=50)
    p.add_argument("--stops", type=int, default=40)
    p.add_argument("--flood", type=int, default=8, help="here() queries the flooding app keeps outstanding")
    p.add_argument("--names", type=int, default=20000,
                   help="queries, each from an application name of its own, per flood round")
    p.add_argument("--name-rounds", type=int, default=10, dest="name_rounds",
                   help="stops right after a flood of names (and as many baseline stops)")
    args = p.parse_args()
    print(json.dumps(asyncio.run(bench(args)), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
