"""Load benchmark: many clients against the sim, and a vision node asked faster than it grabs.

Each part has a baseline measured in the same run, and the ratios against it. Prints one JSON object.

1. **sim**: ``aioadept sim --state-endpoint none`` (real-time motion) as a child process, and N concurrent
   ``RobotClient`` connections in this process, each doing ``here`` round trips one after another for
   ``--sim-seconds``, capped at ``--sim-max-per-client``. The baseline is 1 client. Reported:
   - p50/p99 round trip and throughput (acks/s), at rest and while one more client moves the arm (move + break,
     real-time motion), which shows what the single serial executor (V+'s one task) does to everyone else;
   - CPU of the sim process (``/proc/PID/stat``, all threads), of this process (the clients' event loop,
     ``os.times``) and of the whole machine (``/proc/stat``), as % of one core (machine: % of all cores);
   - the executor's share: the cost of one ``here`` through the sim's framer, controller (the single V+-like task)
     and ack encoder, measured in-process with no I/O, times the throughput, divided by the sim's CPU rate;
   - CPU microseconds per ack on each side, which do not depend on what else the machine runs.
2. **vision**: a sim at rest with its state stream at the paper's approach pose, and ``aioadept vision``
   (virtual camera at ``--fps``, policy ``after``, sharpness graph) as child processes. One ``Communicator`` sends
   ``VisionRequest`` events open-loop at fixed rates for ``--vision-seconds`` each. The baseline rate is below the
   frame rate. Reported:
   - p50/p99 latency and served/failed counts (error answers, timeouts);
   - the node's CPU, with its idle CPU (grabbing frames, no requests) measured first;
   - the latency split, from each response: ``frame_after_request`` (policy ``after``: the answering frame is
     exposed after the request), ``graph`` (the sharpness graph), and ``rest`` = the frame's production (waiting
     for a covering state sample, rendering) + queueing behind other requests + transport. ``queue_*_est`` is the
     rest beyond the baseline's rest;
   - the re-publications: the Communicator re-sends a request not answered within 20 ms (then 40, 80 ms ...).

A one-second window before anything starts records how busy the machine already is (``background``); each window
also reports ``others_cpu_pct``, the CPU of everything else. Every child is started on 127.0.0.1, port 0, and
waited for on its ``READY`` line. The run is bounded: about ``3 x sim-seconds + len(rates) x vision-seconds + 20
s``, with a hard cap of ``--max-seconds``.

Usage: ``python benchmarks/bench_load.py [--clients 50] [--sim-seconds 3] [--vision-rates 10,50,150,300]
[--vision-seconds 5] [--fps 15]``
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import statistics
import sys
import time
from typing import Any

from aioadept.apps.paper import INIT_MOVE
from aioadept.bus.communicator import Communicator
from aioadept.client import RobotClient
from aioadept.commands import MoveRelJoints
from aioadept.errors import AdeptError
from verdicts import verdict

CLK_TCK = os.sysconf("SC_CLK_TCK")
NCPU = os.cpu_count() or 1


# ------------------------------------------------------------------------------------------------ measuring CPU
def proc_cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` (all its threads) from /proc/PID/stat."""
    with open(f"/proc/{pid}/stat") as fh:
        fields = fh.read().rpartition(")")[2].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # utime, stime (fields 14, 15 of proc(5))


def self_cpu_s() -> float:
    t = os.times()
    return t.user + t.system


def machine_ticks() -> tuple[int, int]:
    """(busy, total) jiffies over all cores, from /proc/stat."""
    with open("/proc/stat") as fh:
        vals = [int(v) for v in fh.readline().split()[1:]]
    idle = vals[3] + (vals[4] if len(vals) > 4 else 0)  # idle + iowait
    total = sum(vals[:8])  # user nice system idle iowait irq softirq steal (guest is counted in user)
    return total - idle, total


class CpuWindow:
    """CPU of a child, of this process and of the machine between ``start()`` and ``stop()``."""

    def __init__(self, pid: int) -> None:
        self.pid = pid

    def start(self) -> CpuWindow:
        self.t0 = time.monotonic()
        self.child0, self.self0, self.mach0 = proc_cpu_s(self.pid), self_cpu_s(), machine_ticks()
        return self

    def stop(self) -> dict[str, float]:
        wall = time.monotonic() - self.t0
        child, me, mach = proc_cpu_s(self.pid), self_cpu_s(), machine_ticks()
        busy, total = mach[0] - self.mach0[0], mach[1] - self.mach0[1]
        child_pct, self_pct = 100 * (child - self.child0) / wall, 100 * (me - self.self0) / wall
        machine_pct = 100 * busy / total if total else 0.0
        return {
            "wall_s": round(wall, 3),
            "child_cpu_pct": round(child_pct, 1),
            "self_cpu_pct": round(self_pct, 1),
            "machine_cpu_pct": round(machine_pct, 1),
            # Everything else on the machine (other users' processes, the kernel's softirq work), % of one core.
            "others_cpu_pct": round(max(0.0, machine_pct * NCPU - child_pct - self_pct), 1),
        }


def pct(samples: list[float], q: float) -> float:
    s = sorted(samples)
    return s[min(len(s) - 1, int(q * len(s)))]


def ms(v: float) -> float:
    return round(v * 1e3, 3)


# ------------------------------------------------------------------------------------------------ child processes
async def start_node(*argv: str) -> tuple[asyncio.subprocess.Process, dict[str, str]]:
    proc = await asyncio.create_subprocess_exec(sys.executable, "-m", "aioadept", *argv,
                                                stdin=asyncio.subprocess.DEVNULL, stdout=asyncio.subprocess.PIPE,
                                                stderr=asyncio.subprocess.DEVNULL)
    assert proc.stdout is not None
    try:
        async with asyncio.timeout(30):
            while True:
                line = (await proc.stdout.readline()).decode()
                if not line:
                    raise RuntimeError(f"{argv[0]} exited ({await proc.wait()}) before READY")
                if line.startswith("READY"):
                    return proc, dict(f.split("=", 1) for f in line.split()[1:] if "=" in f)
    except BaseException:
        await stop_node(proc)
        raise


async def stop_node(proc: asyncio.subprocess.Process) -> None:
    if proc.returncode is None:
        proc.terminate()
        try:
            async with asyncio.timeout(10):
                await proc.wait()
        except TimeoutError:
            proc.kill()
            await proc.wait()


# ------------------------------------------------------------------------------------------------ 1: the sim
def executor_cost_s(n: int = 20000) -> float:
    """CPU seconds per ``here`` through the sim's framer + controller + ack encoder, no I/O (best of 3; process
    time, so a busy machine does not inflate it)."""
    from aioadept.protocol import LineFramer, encode_ack
    from aioadept.sim.controller import Controller

    ctl = Controller(instant=True)
    ctl.connect(1)
    framer = LineFramer()
    lines = [b"%08x:here\r\n" % i for i in range(n)]
    best = float("inf")
    for _ in range(3):
        t0 = time.process_time()
        for i, line in enumerate(lines):
            for item in framer.feed(line):
                for o in ctl.handle(item, 1, i * 1e-4):
                    encode_ack(o.ack)
        best = min(best, (time.process_time() - t0) / n)
    return best


async def sim_case(host: str, port: int, pid: int, n_clients: int, seconds: float, cap: int, *,
                   mover: bool = False) -> dict[str, Any]:
    """``n_clients`` doing ``here`` round trips; with ``mover``, one more client moves J1 back and forth by 10
    degrees (move + break, real-time motion) all the while, as a cell's own program would."""
    loop = asyncio.get_running_loop()
    clients = [RobotClient(host, port, ack_timeout_s=10.0) for _ in range(n_clients)]
    mover_client = RobotClient(host, port, ack_timeout_s=10.0) if mover else None
    await asyncio.gather(*(c.connect() for c in clients), *([mover_client.connect()] if mover_client else []))
    latencies: list[float] = []
    errors: list[str] = []
    moves = 0
    try:
        await asyncio.gather(*(c.here() for c in clients for _ in range(5)))  # warm-up
        t_end = loop.time() + seconds

        async def run(c: RobotClient) -> None:
            n = 0
            while n < cap and loop.time() < t_end:
                t0 = loop.time()
                try:
                    await c.here()
                except AdeptError as exc:
                    errors.append(f"{type(exc).__name__}: {exc}")
                    return
                latencies.append(loop.time() - t0)
                n += 1

        async def move() -> None:
            nonlocal moves
            assert mover_client is not None
            while loop.time() < t_end:
                await mover_client.cmdexec(MoveRelJoints([10.0 if moves % 2 == 0 else -10.0, 0, 0, 0, 0, 0]))
                moves += 1

        cpu = CpuWindow(pid).start()
        await asyncio.gather(*(run(c) for c in clients), *([move()] if mover else []))
        window = cpu.stop()
    finally:
        await asyncio.gather(*(c.close() for c in [*clients, *([mover_client] if mover_client else [])]),
                             return_exceptions=True)
    return {
        "clients": n_clients,
        **({"mover_moves": moves} if mover else {}),
        "acks": len(latencies),
        "errors": len(errors),
        "first_error": errors[0] if errors else None,
        "p50_us": round(pct(latencies, 0.50) * 1e6, 1),
        "p99_us": round(pct(latencies, 0.99) * 1e6, 1),
        "mean_us": round(statistics.fmean(latencies) * 1e6, 1),
        "acks_per_s": round(len(latencies) / window["wall_s"], 1),
        "sim_cpu_pct": window["child_cpu_pct"],
        "client_loop_cpu_pct": window["self_cpu_pct"],
        # CPU per ack: what each side costs per message, whatever else the machine runs.
        "sim_cpu_us_per_ack": round(window["child_cpu_pct"] / 100 * window["wall_s"] / max(1, len(latencies)) * 1e6,
                                    1),
        "client_cpu_us_per_ack": round(window["self_cpu_pct"] / 100 * window["wall_s"] / max(1, len(latencies))
                                       * 1e6, 1),
        "machine_cpu_pct": window["machine_cpu_pct"],
        "others_cpu_pct": window["others_cpu_pct"],
        "wall_s": window["wall_s"],
    }


def sim_verdict(load: dict[str, Any], exec_share: float, moving: dict[str, Any] | None) -> str:
    sim, cli, mach = load["sim_cpu_pct"], load["client_loop_cpu_pct"], load["machine_cpu_pct"]
    head = ""
    if moving is not None and moving["p50_us"] > 5 * load["p50_us"]:
        head = (f"with the arm moving, the single-task design comes first: every here waits behind the mover's "
                f"break (p50 {moving['p50_us'] / 1e3:.1f} ms vs {load['p50_us'] / 1e3:.1f} ms at rest). At rest: ")
    return head + _cpu_verdict(sim, cli, mach, load["others_cpu_pct"], exec_share, load)


def _cpu_verdict(sim: float, cli: float, mach: float, others: float, exec_share: float,
                 load: dict[str, Any]) -> str:
    if sim >= 85 and sim >= cli:
        where = "the sim process (one asyncio thread) is CPU-bound"
        if exec_share >= 0.5:
            return f"{where}, mostly in its serial executor ({exec_share:.0%} of its CPU)"
        return (f"{where}, mostly in asyncio stream I/O around the executor (the serial executor itself is "
                f"{exec_share:.0%} of its CPU)")
    if cli >= 85:
        return f"the clients' event loop is CPU-bound ({cli:g}% of a core) before the sim ({sim:g}%)"
    if mach >= 85:
        return (f"the machine's CPU ({mach:g}% of {NCPU} cores; sim {sim:g}%, clients {cli:g}%, other processes "
                f"{others:g}% of a core) before any one process")
    return (f"nothing saturated (sim {sim:g}%, client loop {cli:g}%, machine {mach:g}%): the round trip bounds "
            f"the throughput")


async def bench_sim(args: argparse.Namespace) -> dict[str, Any]:
    cost = executor_cost_s()
    # Real-time motion (no --instant) for the mover case; ``here`` costs the same either way.
    proc, ready = await start_node("sim", "--port", "0", "--state-endpoint", "none",
                                   "--max-clients", str(args.clients + 4), "--log-level", "ERROR")
    try:
        host, port = ready["host"], int(ready["port"])
        base = await sim_case(host, port, proc.pid, 1, args.sim_seconds, args.sim_max_per_client)
        load = await sim_case(host, port, proc.pid, args.clients, args.sim_seconds, args.sim_max_per_client)
        moving = await sim_case(host, port, proc.pid, args.clients, args.sim_seconds, args.sim_max_per_client,
                                mover=True)
    finally:
        await stop_node(proc)
    exec_share = load["acks_per_s"] * cost / max(load["sim_cpu_pct"] / 100, 1e-9)
    return {
        "executor_us_per_here": round(cost * 1e6, 2),
        "baseline_1_client": base,
        "load": load,
        "load_arm_moving": moving,
        "ratios": {
            "p50": round(load["p50_us"] / base["p50_us"], 2),
            "p99": round(load["p99_us"] / base["p99_us"], 2),
            "throughput": round(load["acks_per_s"] / base["acks_per_s"], 2),
            "sim_cpu": round(load["sim_cpu_pct"] / max(base["sim_cpu_pct"], 0.1), 2),
            "p50_arm_moving_vs_rest": round(moving["p50_us"] / load["p50_us"], 2),
        },
        "executor_share_of_sim_cpu": round(exec_share, 3),
        "little_law_p50_estimate_us": round(args.clients / load["acks_per_s"] * 1e6, 1),
        "saturates_first": sim_verdict(load, exec_share, moving),
    }


# ------------------------------------------------------------------------------------------------ 2: vision
async def vision_case(comm: Communicator, pid: int, rate: float, seconds: float, timeout_s: float) -> dict[str, Any]:
    loop = asyncio.get_running_loop()
    n = max(1, round(rate * seconds))
    results: list[Any] = []
    republished0 = comm.republished

    async def one() -> None:
        try:
            results.append(await comm.request("VisionRequest", {}, timeout_s=timeout_s))
        except AdeptError as exc:
            results.append(exc)

    cpu = CpuWindow(pid).start()
    t0 = loop.time()
    tasks = []
    for i in range(n):  # open loop: request i leaves at t0 + i/rate, whatever the answers do
        delay = t0 + i / rate - loop.time()
        if delay > 0:
            await asyncio.sleep(delay)
        tasks.append(asyncio.create_task(one()))
    send_wall = loop.time() - t0
    await asyncio.gather(*tasks)
    window = cpu.stop()
    ok = [r for r in results if not isinstance(r, Exception) and "error" not in r.attributes]
    errs = [r for r in results if not isinstance(r, Exception) and "error" in r.attributes]
    timeouts = [r for r in results if isinstance(r, Exception)]
    lat = [r.latency_s for r in ok]
    wait = [max(0.0, -r.attributes["frame_age_ms"] / 1e3) for r in ok]
    proc = [r.attributes["proc_time_ms"] / 1e3 for r in ok]
    rest = [a - b - c for a, b, c in zip(lat, wait, proc, strict=True)]
    frames = {r.attributes.get("frame_seq") for r in ok}
    out: dict[str, Any] = {
        "rate_req_per_s": rate,
        "requests": n,
        "sent_rate_req_per_s": round(n / send_wall, 1) if send_wall > 0 else None,
        "served": len(ok),
        "failed": len(errs) + len(timeouts),
        "failed_error_answers": len(errs),
        "failed_timeouts": len(timeouts),
        "first_failure": (errs[0].attributes["error"] if errs else
                          f"{type(timeouts[0]).__name__}: {timeouts[0]}" if timeouts else None),
        "republished": comm.republished - republished0,
        "distinct_frames": len(frames),
        "node_cpu_pct": window["child_cpu_pct"],
        "mcn_loop_cpu_pct": window["self_cpu_pct"],
        "machine_cpu_pct": window["machine_cpu_pct"],
        "others_cpu_pct": window["others_cpu_pct"],
        "wall_s": window["wall_s"],
    }
    if ok:
        out.update({
            "p50_ms": ms(pct(lat, 0.5)), "p99_ms": ms(pct(lat, 0.99)), "mean_ms": ms(statistics.fmean(lat)),
            "frame_after_request_p50_ms": ms(pct(wait, 0.5)), "frame_after_request_p99_ms": ms(pct(wait, 0.99)),
            "graph_p50_ms": ms(pct(proc, 0.5)), "graph_p99_ms": ms(pct(proc, 0.99)),
            "rest_p50_ms": ms(pct(rest, 0.5)), "rest_p99_ms": ms(pct(rest, 0.99)),
        })
    return out


def vision_verdict(base: dict[str, Any], loads: list[dict[str, Any]], fps: float) -> str:
    """The first rate above the frame rate where something gives, and what."""
    above = [c for c in loads if c["rate_req_per_s"] > fps]
    if not above or "p50_ms" not in base:
        return "no rate above the frame rate was measured (or the baseline failed)"
    for c in above:
        rate = c["rate_req_per_s"]
        cpu, mach, others = c["node_cpu_pct"], c["machine_cpu_pct"], c["others_cpu_pct"]
        limit = ("the node's CPU" if cpu >= 85 else
                 f"the machine's CPU ({mach:g}%, other processes {others:g}% of a core)" if mach >= 85 else
                 "the one-request-at-a-time Responder")
        if c["failed"] or c["served"] < 0.95 * c["requests"]:
            return (f"at {rate:g} req/s requests fail ({c['failed']} of {c['requests']}: {c['first_failure']}); "
                    f"limited by {limit} (node CPU {cpu:g}%)")
        if "p50_ms" in c and (c["queue_p50_ms_est"] > max(10.0, 0.5 * base["p50_ms"])
                              or c["p99_ms"] > 3 * base["p99_ms"]):
            return (f"at {rate:g} req/s requests queue (p50 {c['p50_ms']:g} ms, p99 {c['p99_ms']:g} ms vs "
                    f"{base['p50_ms']:g} / {base['p99_ms']:g} ms at {base['rate_req_per_s']:g} req/s; "
                    f"{c['republished']} re-publications); limited by {limit} (node CPU {cpu:g}%)")
    c = above[-1]
    return (f"nothing queues up to {c['rate_req_per_s']:g} req/s: the latency is the frame wait (exposure "
            f"{c['frame_after_request_p50_ms']:g} ms after the request, p50, then the frame's production) plus the "
            f"graph ({c['graph_p50_ms']:g} ms); requests share frames ({c['distinct_frames']} frames for "
            f"{c['served']} answers)")


async def bench_vision(args: argparse.Namespace) -> dict[str, Any]:
    sim, sready = await start_node("sim", "--port", "0", "--instant", "--state-endpoint", "tcp://127.0.0.1:0",
                                   "--log-level", "ERROR")
    try:
        async with RobotClient(sready["host"], int(sready["port"])) as rc:
            await rc.cmdexec(*INIT_MOVE)  # the paper's approach pose: the target is in view
        vis, vready = await start_node("vision", "--state-endpoint", sready["state"], "--request-endpoint",
                                       "tcp://127.0.0.1:0", "--response-endpoint", "tcp://127.0.0.1:0",
                                       "--fps", f"{args.fps:g}", "--policy", "after", "--seed", "1",
                                       "--log-level", "WARNING")
        try:
            async with Communicator(vready["request"], vready["response"], timeout_s=args.vision_timeout) as comm:
                for _ in range(5):  # warm-up, and the subscription is surely joined
                    await comm.request("VisionRequest", {})
                idle = CpuWindow(vis.pid).start()
                await asyncio.sleep(args.idle_seconds)  # measuring the idle node's CPU, not waiting for readiness
                idle_cpu = idle.stop()
                cases = [await vision_case(comm, vis.pid, rate, args.vision_seconds, args.vision_timeout)
                         for rate in args.vision_rates]
        finally:
            await stop_node(vis)
    finally:
        await stop_node(sim)
    base = cases[0]
    for c in cases:
        # CPU per request above the idle node (which grabs frames whether asked or not).
        c["node_cpu_ms_per_request_above_idle"] = round(
            max(0.0, c["node_cpu_pct"] - idle_cpu["child_cpu_pct"]) / 100 * c["wall_s"] / max(1, c["requests"]) * 1e3,
            3)
        # The rest beyond the baseline's rest: waiting behind other requests.
        if "rest_p50_ms" in c and "rest_p50_ms" in base:
            c["queue_p50_ms_est"] = round(max(0.0, c["rest_p50_ms"] - base["rest_p50_ms"]), 3)
            c["queue_p99_ms_est"] = round(max(0.0, c["rest_p99_ms"] - base["rest_p99_ms"]), 3)
    out: dict[str, Any] = {
        "fps": args.fps,
        "policy": "after",
        "graph": "sharpness",
        "idle_node_cpu_pct": idle_cpu["child_cpu_pct"],
        "baseline": base,
        "loads": cases[1:],
        "ratios": [],
        "saturates_first": vision_verdict(base, cases[1:], args.fps),
    }
    for c in cases[1:]:
        r: dict[str, Any] = {"rate_req_per_s": c["rate_req_per_s"]}
        if "p50_ms" in c and "p50_ms" in base:
            r.update(p50=round(c["p50_ms"] / base["p50_ms"], 2), p99=round(c["p99_ms"] / base["p99_ms"], 2))
        r["node_cpu"] = round(c["node_cpu_pct"] / max(base["node_cpu_pct"], 0.1), 2)
        r["node_cpu_above_idle"] = round((c["node_cpu_pct"] - idle_cpu["child_cpu_pct"])
                                         / max(base["node_cpu_pct"] - idle_cpu["child_cpu_pct"], 0.1), 2)
        out["ratios"].append(r)
    return out


# ------------------------------------------------------------------------------------------------ main
async def main_async(args: argparse.Namespace) -> dict[str, Any]:
    out: dict[str, Any] = {"benchmark": "load", "python": platform.python_version(), "machine": platform.machine(),
                           "cpus": NCPU}
    # What else the machine is doing (other users' tests...): the figures below are only as clean as this.
    t0, m0 = time.monotonic(), machine_ticks()
    await asyncio.sleep(1.0)  # a measuring window, not a readiness wait
    m1 = machine_ticks()
    out["background"] = {"loadavg_1m_at_start": round(os.getloadavg()[0], 2),
                         "machine_cpu_pct_before_start": round(100 * (m1[0] - m0[0]) / max(1, m1[1] - m0[1]), 1),
                         "window_s": round(time.monotonic() - t0, 2)}
    async with asyncio.timeout(args.max_seconds):
        if not args.skip_sim:
            out["sim"] = await bench_sim(args)
        if not args.skip_vision:
            out["vision"] = await bench_vision(args)
    out["verdicts"] = load_verdicts(out, args)
    return out


def load_verdicts(out: dict[str, Any], args: argparse.Namespace) -> list[dict[str, Any]]:
    """Figures against their baselines; this benchmark finds what saturates first and states no goal."""
    v = []
    if "sim" in out:
        s = out["sim"]
        v.append(verdict(f"sim here p50, {args.clients} clients vs 1", s["load"]["p50_us"],
                         s["baseline_1_client"]["p50_us"], unit="us"))
        v.append(verdict(f"sim here p50, {args.clients} clients, arm moving vs at rest",
                         s["load_arm_moving"]["p50_us"], s["load"]["p50_us"], unit="us"))
    if "vision" in out:
        base = out["vision"]["baseline"]
        for c in out["vision"]["loads"]:
            if "p50_ms" in c and "p50_ms" in base:
                v.append(verdict(f"vision p50 at {c['rate_req_per_s']:g} vs {base['rate_req_per_s']:g} req/s",
                                 c["p50_ms"], base["p50_ms"], unit="ms"))
    return v


def floats(s: str) -> list[float]:
    return [float(v) for v in s.split(",") if v]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--clients", type=int, default=50, help="concurrent sim clients under load (baseline: 1)")
    p.add_argument("--sim-seconds", type=float, default=3.0, help="length of each sim case")
    p.add_argument("--sim-max-per-client", type=int, default=50_000, help="round trips per client at most")
    p.add_argument("--vision-rates", type=floats, default=[10.0, 50.0, 150.0, 300.0],
                   help="request rates, req/s; the first is the baseline and should be below --fps")
    p.add_argument("--vision-seconds", type=float, default=5.0, help="length of each vision rate")
    p.add_argument("--vision-timeout", type=float, default=2.0, help="per request, s (then counted as failed)")
    p.add_argument("--idle-seconds", type=float, default=2.0, help="window for the idle node's CPU")
    p.add_argument("--fps", type=float, default=15.0, help="the vision node's frame rate")
    p.add_argument("--skip-sim", action="store_true")
    p.add_argument("--skip-vision", action="store_true")
    p.add_argument("--max-seconds", type=float, default=240.0, help="hard cap on the whole run")
    args = p.parse_args(argv)
    if args.vision_rates[0] >= args.fps:
        p.error("the first --vision-rates value is the baseline and must be below --fps")
    print(json.dumps(asyncio.run(main_async(args)), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
