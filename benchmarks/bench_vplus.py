"""The V+ emulator: interpreter speed, and the shipped ``vplus/`` server against the Python sim over TCP.

Three figures, each against a baseline measured in the same run (prints one JSON object):

- **loop**: ``FOR i = 1 TO N`` with assignments and a string ``$DECODE`` (4 simple statements per iteration: the
  FOR step and three assignments) in the emulator vs the same loop in plain Python. Goal: >= 1 M statements/s.
- **here round trip**: ``aioadept sim --vplus vplus/rserver.V2 vplus/rsskills.V2 vplus/rsconfig.V2 --run rs.main``
  vs ``aioadept sim`` (the Python skill table), both child processes, this process the client: write ``ID:here``,
  read its ack, one after another. Goal: p50 of the emulated server <= 1.5x the Python sim's.
- **stop**: the shipped server in the emulator in this process, a J1 move at speed and a ``stop`` from another
  client: ms from the stop written to ``BRAKE`` acting on the arm, and where the rest of the way to the
  ``break``'s ``aborted`` ack goes (the deceleration, the BREAK's wake-up); baseline: the Python sim's stop ->
  ``aborted`` ack (a child process, motion in real time). Goal: <= 2 V+ trajectory cycles (32 ms), p95.
- **debugger attached**: the same loop with the V+ debugger attached and no breakpoint (the instrumented form,
  aioadept.vplus.trace) vs no debugger, best of 3 runs each in turns. Goal: <= 1.5x.
- **pipelined throughput**: 10 ``here`` lines written at once, then their 10 acks read; acks per second.
  Goal: emulated >= 0.5x the Python sim.

Both servers run side by side, one connection each, warmed up; then ``--blocks`` measurement blocks alternate
between them (the order swapped every block), and each block yields a ratio. The verdicts use the median of the
per-block ratios and the JSON gives their min and max: on a shared machine the load changes within seconds, and
neighbouring blocks see nearly the same load. The blocks are short (50 round trips, 3 to 50 ms) and many (100): a
pair of them a few ms apart sees the same load, where blocks of 300-500 (a quarter of a second or more each) gave
run medians from 1.1 to 2.5 within one hour on a shared machine (docs/vplus.md, Performance). The JSON also gives
``here_p10_ratio_all``, the ratio of the two servers' fastest tenth of round trips, which load spikes miss; the
median's 95 % confidence interval (``ci95``: what the same load would give again; a run whose interval holds the
goal has not shown it missed or met); and each server's CPU time per ack (``cpu_us_per_ack``, /proc: user +
system time over the measurement blocks), the cost of the code, which the load changes less than the waits.

Usage: ``python benchmarks/bench_vplus.py [--quick] [--messages 50] [--blocks 100] [--loop 1000000]``.
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
from pathlib import Path

from verdicts import verdict

from aioadept.vplus import Emulator

ROOT = Path(__file__).resolve().parents[1]
VPLUS_FILES = [str(ROOT / "vplus" / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]


# -- the interpreter -----------------------------------------------------------------------------------------

def loop_source(n: int) -> str:
    return f""".PROGRAM bench()
    FOR i = 1 TO {n}
        x = i*2
        $s = "ab,cd"
        $t = $DECODE($s, ",", 0)
    END
.END
"""


def plain_python(n: int) -> None:
    g: dict = {}
    i = 1.0
    while i <= n:
        g["x"] = i * 2
        s = "ab,cd"
        k = s.find(",")
        g["t"], g["s"] = s[:k], s[k:]
        i += 1.0


def bench_loop(n: int) -> dict:
    emu = Emulator.from_source(loop_source(n), robot=False)
    t0 = time.perf_counter()
    emu.call("bench")
    t_vplus = time.perf_counter() - t0
    t0 = time.perf_counter()
    plain_python(n)
    t_py = time.perf_counter() - t0
    stmts = 4 * n
    return {"iterations": n, "statements": stmts, "vplus_s": round(t_vplus, 3), "python_baseline_s": round(t_py, 3),
            "statements_per_s": round(stmts / t_vplus), "ratio_vs_python": round(t_vplus / t_py, 2)}


def bench_debugger_loop(n: int, rounds: int = 3) -> dict:
    """The loop with the debugger attached (aioadept.vplus.debugger: the instrumented form, no breakpoint) vs
    without, in turns; each side's best of ``rounds`` (the machine's load changes between runs)."""
    from aioadept.vplus.debugger import Debugger

    best = {"none": float("inf"), "attached": float("inf")}
    for _ in range(rounds):
        for side in best:
            emu = Emulator.from_source(loop_source(n), robot=False)
            if side == "attached":
                Debugger(emu.rt)
            t0 = time.perf_counter()
            emu.call("bench")
            best[side] = min(best[side], time.perf_counter() - t0)
    stmts = 4 * n
    return {"iterations": n, "no_debugger_s": round(best["none"], 3), "debugger_s": round(best["attached"], 3),
            "no_debugger_statements_per_s": round(stmts / best["none"]),
            "debugger_statements_per_s": round(stmts / best["attached"]),
            "ratio": round(best["attached"] / best["none"], 2)}


# -- the stop, step by step -----------------------------------------------------------------------------------

CYCLE_MS = 16.0
"""A V+ trajectory (major) cycle (V+ Language User's Guide, "Scheduling of Program Execution Tasks")."""


async def stop_breakdown(trials: int) -> dict:
    """The shipped server in the emulator in this process (real clock, real TCP on 127.0.0.1, the simulated
    Viper moving in real time), a mover client (a long J1 move and a ``break``) and a stopper client: where
    each millisecond from ``stop`` written to the ``break``'s ``aborted`` ack goes. Stamps: the stop written;
    its bytes handed to the emulator by asyncio (``data_received``: the kernel and the event loop); ``BRAKE``
    called on the arm (the reader's wake-up, its V+ parsing the line); the arm at rest (the deceleration the
    motion model computes at the BRAKE); the ``aborted`` ack read by the mover (the BREAK's wake-up, the
    executor, the write). Medians and p95 over ``trials``."""
    from aioadept.ports import free_port
    from aioadept.vplus import RealClock
    from aioadept.vplus.iodev import Network, _Proto
    from aioadept.vplus.loader import load_files
    from aioadept.vplus.robot import RobotDevice
    from aioadept.sim.controller import Controller

    clock = RealClock()
    emu = Emulator(load_files(VPLUS_FILES), robot=RobotDevice(Controller()), clock=clock, console=lambda t, x: None)
    port = free_port()
    listening = asyncio.Event()
    emu.rt.devices = Network("127.0.0.1", {1234: port, 1235: free_port()},
                             lambda vport, host, p: listening.set() if vport == 1234 else None)
    stamps: dict[str, float] = {}
    data_received = _Proto.data_received

    def stamped_data(proto, data: bytes) -> None:
        if b":stop" in data and "t0" in stamps:
            stamps.setdefault("data", time.monotonic())
        data_received(proto, data)

    arm = emu.rt.robot
    brake = arm.brake

    def stamped_brake(now_s=None) -> float:
        rest = brake(now_s)
        if "t0" in stamps and "brake" not in stamps:
            stamps["brake"] = time.monotonic()
            stamps["rest"] = clock._t0 + rest           # the runtime's time is monotonic seconds since _t0
        return rest

    _Proto.data_received = stamped_data
    arm.brake = stamped_brake
    halt = asyncio.Event()
    emu.execute(0, "rs.main")
    served = asyncio.ensure_future(emu.serve(halt))
    parts: dict[str, list[float]] = {k: [] for k in ("to_emulator", "to_brake", "decelerate", "to_ack", "total",
                                                      "written_to_brake")}
    try:
        await asyncio.wait_for(listening.wait(), 30)
        async for t_ack in stop_trials(port, trials, stamps):
            if "brake" not in stamps or "data" not in stamps:
                continue
            t0, t_data, t_brake, t_rest = stamps["t0"], stamps["data"], stamps["brake"], stamps["rest"]
            for k, v in (("to_emulator", t_data - t0), ("to_brake", t_brake - t_data),
                         ("decelerate", t_rest - t_brake), ("to_ack", t_ack - t_rest), ("total", t_ack - t0),
                         ("written_to_brake", t_brake - t0)):
                parts[k].append(v * 1e3)
    finally:
        _Proto.data_received = data_received
        halt.set()
        await asyncio.wait_for(served, 10)
    out: dict = {"trials": trials, "counted": len(parts["total"]), "cycle_ms": CYCLE_MS}
    for k, xs in parts.items():
        xs.sort()
        out[k + "_ms"] = {"p50": round(_p50(xs), 2), "p95": round(xs[min(len(xs) - 1, int(len(xs) * 0.95))], 2)}
    return out


async def stop_trials(port: int, trials: int, stamps: dict[str, float]):
    """Per trial: a mover's long J1 move and ``break``, 0.3 s later (the arm at speed) a stopper's ``stop``
    (``stamps["t0"]``, stamps cleared first); yields the time the mover read its break's ``aborted`` (a break that
    completed instead is not counted)."""
    mover = Conn(*await asyncio.open_connection("127.0.0.1", port))
    stopper = Conn(*await asyncio.open_connection("127.0.0.1", port))
    try:
        for i in range(trials):
            target = 150 if i % 2 == 0 else -150
            m, b, st = b"m%07d" % i, b"b%07d" % i, b"s%07d" % i
            mover.writer.write(m + b":move_joints:%d,-90,180,0,90,0\r\n" % target + b + b":break\r\n")
            await asyncio.wait_for(_until(mover, m), 30)
            await asyncio.sleep(0.3)
            stamps.clear()
            stamps["t0"] = time.monotonic()
            stopper.writer.write(st + b":stop\r\n")
            line = await asyncio.wait_for(_until(mover, b), 30)
            t_ack = time.monotonic()
            await asyncio.wait_for(_until(stopper, st), 30)
            if b":aborted:" in line:
                yield t_ack
    finally:
        for c in (mover, stopper):
            await c.close()


async def python_sim_stop(trials: int) -> dict:
    """The baseline: the Python sim (a child process, motion in real time) acks the ``break`` ``aborted`` the
    moment it has braked, so stop written -> that ack is its stop-to-brake latency (plus the ack's way back)."""
    aioadept = str(Path(sys.executable).parent / "aioadept")
    proc, port = await start([aioadept, "sim", "--port", "0", "--state-endpoint", "none"])
    stamps: dict[str, float] = {}
    try:
        xs = sorted([(t_ack - stamps["t0"]) * 1e3 async for t_ack in stop_trials(port, trials, stamps)])
    finally:
        await stop(proc)
    return {"trials": trials, "counted": len(xs), "p50_ms": round(_p50(xs), 2),
            "p95_ms": round(xs[min(len(xs) - 1, int(len(xs) * 0.95))], 2)}


async def _until(conn: "Conn", mid: bytes) -> bytes:
    while True:
        line = await conn.reader.readuntil(b"\r\n")
        if line.startswith(mid + b":"):
            return line


# -- the servers ---------------------------------------------------------------------------------------------

async def start(argv: list[str]) -> tuple[asyncio.subprocess.Process, int]:
    """Start a server; its port comes from its READY line (the emulator prints TYPE lines before it)."""
    proc = await asyncio.create_subprocess_exec(*argv, stdout=asyncio.subprocess.PIPE,
                                                stderr=asyncio.subprocess.DEVNULL)
    assert proc.stdout is not None
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        line = (await asyncio.wait_for(proc.stdout.readline(), 30)).decode()
        if not line:
            break
        if line.startswith("READY"):
            fields = dict(f.split("=", 1) for f in line.split()[1:])
            asyncio.ensure_future(_drain(proc.stdout))
            return proc, int(fields["port"])
    proc.kill()
    raise RuntimeError(f"server did not start: {argv}")


async def _drain(stream: asyncio.StreamReader) -> None:
    while await stream.readline():
        pass


async def stop(proc: asyncio.subprocess.Process) -> None:
    if proc.returncode is None:
        proc.terminate()
        await proc.wait()


class Conn:
    """One client connection to a server, kept open for the whole run (blocks alternate between servers)."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer, self.seq = reader, writer, 0

    @classmethod
    async def open(cls, port: int) -> Conn:
        r, w = await asyncio.open_connection("127.0.0.1", port)
        return cls(r, w)

    async def close(self) -> None:
        self.writer.close()
        await self.writer.wait_closed()

    def _mid(self) -> bytes:
        self.seq += 1
        return b"m%07d" % (self.seq % 10_000_000)

    async def round_trips(self, n: int) -> list[float]:
        """``n`` ``here`` round trips one after another; their durations (s)."""
        loop = asyncio.get_running_loop()
        samples: list[float] = []
        for _ in range(n):
            mid = self._mid()
            t0 = loop.time()
            self.writer.write(mid + b":here\r\n")
            line = await self.reader.readuntil(b"\n")
            samples.append(loop.time() - t0)
            if not line.startswith(mid + b":done"):
                raise RuntimeError(f"unexpected ack: {line!r}")
        return samples

    async def pipelined(self, batches: int, depth: int = 10) -> float:
        """``batches`` times: ``depth`` ``here`` lines written at once, then their acks read; acks per second."""
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        for _ in range(batches):
            mids = [self._mid() for _ in range(depth)]
            self.writer.write(b"".join(m + b":here\r\n" for m in mids))
            for m in mids:
                line = await self.reader.readuntil(b"\n")
                if not line.startswith(m + b":done"):
                    raise RuntimeError(f"unexpected ack: {line!r}")
        return batches * depth / (loop.time() - t0)


def _p50(xs: list[float]) -> float:
    return statistics.median(xs)


def _spread(xs: list[float], nd: int = 2) -> dict:
    return {"median": round(statistics.median(xs), nd), "min": round(min(xs), nd), "max": round(max(xs), nd)}


def _median_ci95(xs: list[float], nd: int = 2) -> list[float]:
    """A distribution-free 95 % confidence interval of the median of ``xs`` (its order statistics n/2 -+
    0.98 sqrt(n), the normal approximation of the binomial): how far the run's median may be from what the same
    load would give again. Any n >= 1 (few blocks: the whole range)."""
    ys = sorted(xs)
    k = max(0, int(len(ys) / 2 - 0.98 * len(ys) ** 0.5))
    return [round(ys[k], nd), round(ys[len(ys) - 1 - k], nd)]


def _cpu_s(pid: int) -> float | None:
    """User + system CPU seconds of process ``pid`` so far (Linux /proc; None elsewhere)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


async def bench_servers(args: argparse.Namespace) -> dict:
    """Both servers run at once; measurement blocks alternate between them (order swapped each block), so that
    a block of one and its neighbour of the other see the same load of the (shared) machine. Each block gives a
    ratio; the verdicts use the median of those ratios, and the spread (min, max) says how noisy the run was."""
    aioadept = str(Path(sys.executable).parent / "aioadept")
    argvs = {
        "python_sim": [aioadept, "sim", "--port", "0", "--instant", "--state-endpoint", "none"],
        "vplus": [aioadept, "sim", "--vplus", *VPLUS_FILES, "--run", "rs.main", "--map-port", "1234=0",
                  "--map-port", "1235=0", "--instant", "--state-endpoint", "none"],
    }
    procs: dict[str, asyncio.subprocess.Process] = {}
    conns: dict[str, Conn] = {}
    names = list(argvs)
    rtt: dict[str, list[float]] = {n: [] for n in names}        # per-block p50 (s)
    thr: dict[str, list[float]] = {n: [] for n in names}        # per-block acks/s
    all_rtt: dict[str, list[float]] = {n: [] for n in names}
    cpu: dict[str, float | None] = {}
    try:
        for name, argv in argvs.items():
            procs[name], port = await start(argv)
            conns[name] = await Conn.open(port)
        for name in names:                                    # warm-up: not measured
            await conns[name].round_trips(args.warmup)
            await conns[name].pipelined(max(1, args.warmup // 10))
        cpu0 = {n: _cpu_s(procs[n].pid) for n in names}
        for b in range(args.blocks):
            order = names if b % 2 == 0 else names[::-1]
            for name in order:
                s = await conns[name].round_trips(args.messages)
                all_rtt[name] += s
                rtt[name].append(_p50(s))
            for name in order:
                thr[name].append(await conns[name].pipelined(max(1, args.messages // 10)))
        for n in names:
            c0, c1 = cpu0[n], _cpu_s(procs[n].pid)
            acks = args.blocks * (args.messages + 10 * max(1, args.messages // 10))
            cpu[n] = None if c0 is None or c1 is None else round((c1 - c0) / acks * 1e6, 1)
    finally:
        for c in conns.values():
            await c.close()
        for p in procs.values():
            await stop(p)
    out: dict = {"blocks": args.blocks, "messages_per_block": args.messages}
    for n in names:
        xs = sorted(all_rtt[n])
        out[n] = {
            "here_p50_us_per_block": _spread([x * 1e6 for x in rtt[n]], 1),
            "here_all": {"n": len(xs), "p10_us": round(xs[len(xs) // 10] * 1e6, 1),
                         "p50_us": round(xs[len(xs) // 2] * 1e6, 1),
                         "p99_us": round(xs[min(len(xs) - 1, int(len(xs) * 0.99))] * 1e6, 1)},
            "pipelined_acks_per_s_per_block": _spread(thr[n], 0),
            "cpu_us_per_ack": cpu.get(n),
        }
    ratios = [v / s for v, s in zip(rtt["vplus"], rtt["python_sim"], strict=True)]
    out["here_p50_ratio_per_block"] = _spread(ratios) | {"ci95": _median_ci95(ratios)}
    # the fastest tenth of each server's round trips, those no load spike of the shared machine hit: a second
    # figure, steadier under load than any median (the verdict stays the median of per-block ratios)
    out["here_p10_ratio_all"] = round(out["vplus"]["here_all"]["p10_us"] / out["python_sim"]["here_all"]["p10_us"], 2)
    out["pipelined_ratio_per_block"] = _spread([v / s for v, s in zip(thr["vplus"], thr["python_sim"], strict=True)])
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--loop", type=int, default=1_000_000, help="iterations of the V+ FOR loop")
    p.add_argument("--messages", type=int, default=50, help="round trips per server and block")
    p.add_argument("--warmup", type=int, default=300)
    p.add_argument("--blocks", type=int, default=100, help="measurement blocks, alternating between the servers")
    p.add_argument("--stops", type=int, default=20, help="stop trials on each side")
    p.add_argument("--quick", action="store_true", help="a smoke run: fewer iterations and messages")
    args = p.parse_args(argv)
    if args.quick:
        args.loop, args.messages, args.warmup, args.blocks, args.stops = 100_000, 40, 50, 10, 5
    loop = bench_loop(args.loop)
    debug = bench_debugger_loop(args.loop)
    servers = asyncio.run(bench_servers(args))
    stops = asyncio.run(stop_breakdown(args.stops))
    sim_stop = asyncio.run(python_sim_stop(args.stops))
    to_brake = stops["written_to_brake_ms"]["p95"]
    v, s = servers["vplus"], servers["python_sim"]
    rtt_ratio = servers["here_p50_ratio_per_block"]["median"]
    thr_ratio = servers["pipelined_ratio_per_block"]["median"]
    sps = loop["statements_per_s"]
    print(json.dumps({
        "benchmark": "vplus",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "loop": loop,
        "debugger_loop": debug,
        "servers": servers,
        "stop_breakdown": stops,
        "python_sim_stop": sim_stop,
        "verdicts": [
            verdict(f"V+ loop of {args.loop} iterations vs the same loop in Python", loop["vplus_s"],
                    loop["python_baseline_s"], unit="s",
                    goal=">= 1 M V+ statements/s", passed=sps >= 1_000_000),
            verdict(f"V+ loop of {args.loop} iterations with the debugger attached, no breakpoint, vs no debugger "
                    "(best of 3 each, in turns)", debug["debugger_s"], debug["no_debugger_s"], unit="s",
                    ratio=debug["ratio"], goal="ratio <= 1.5", passed=debug["ratio"] <= 1.5),
            verdict("here round trip p50, vplus/ server in the emulator vs the Python sim (median of per-block "
                    "ratios)", v["here_p50_us_per_block"]["median"], s["here_p50_us_per_block"]["median"],
                    unit="us", ratio=rtt_ratio, goal="ratio <= 1.5", passed=rtt_ratio <= 1.5),
            verdict("stop written -> BRAKE acting on the arm, vplus/ server in the emulator, p95 (baseline: the "
                    "Python sim's stop -> break aborted ack, p95)", to_brake, sim_stop["p95_ms"], unit="ms",
                    goal=f"<= 2 trajectory cycles ({2 * CYCLE_MS:g} ms)", passed=to_brake <= 2 * CYCLE_MS),
            verdict("pipelined here acks/s (10 written at once), emulated vs Python sim (median of per-block ratios)",
                    v["pipelined_acks_per_s_per_block"]["median"], s["pipelined_acks_per_s_per_block"]["median"],
                    unit="acks/s", ratio=thr_ratio, goal="ratio >= 0.5", passed=thr_ratio >= 0.5),
        ],
    }, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
