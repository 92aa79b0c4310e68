"""Benchmark: RobotClient against a bare asyncio client, on the same instant-ack server, in the same run.

    .venv/bin/python benchmarks/bench_client.py [--loop asyncio|uvloop] [--quick]

The server runs in a separate process (this script with ``--serve ack|echo``): an asyncio server built on the
protocol core that acks every command at once (``ack``), or a raw line echo (``echo``, the floor of any line
protocol over loopback). The client side, in this process, measures:

- the round trip of one instant skill (p50/p99), as ``cmdexec`` vs a bare client (streams, one write, one
  ``readuntil``), and the bare client against the echo server;
- pipelined throughput of ``cmdexec_joined`` with 10 and 100 messages vs the bare client (one write per batch,
  ``readuntil`` per ack);
- client CPU time (``time.process_time`` of this process) per acked pipelined message.

Configurations alternate in rounds so that drift of this noisy VM hits them alike. Prints one JSON object with
absolute numbers, the ratios RobotClient / bare, the issue's targets, and the profile behind them:
``breakdown_us_per_msg`` (CPU per message of each client stage, in process, no sockets) and
``rtt_amplification`` (the bare client's round trip with 20 us of extra work before each write).

Notes (2-core VM shared with other jobs; see the JSON of your own run, and docs/protocol.md, "Performance"):

- What the client does per message that the bare one does not: validate the ack (split, times, pose, status,
  ID), route it to its submission and build an ``Ack`` and a ``MessageResult`` (frozen, slotted dataclasses) with
  loop-clock times.
- Optimisations, each measured: acks routed in the transport's ``data_received`` (no reader task hop); one waiter
  future per batch; one watchdog timer for all default timeouts (``asyncio.timeout`` cost ~25 us per round trip
  here); framer fast paths (one line; whole CRLF lines) doing the per-line work in C; an inline fast path for plain
  ``done`` acks that reuses the previous ack's Pose object and floats when the pose or times text repeats (times
  have 1 ms resolution, so acks of one millisecond share them); frozen slotted values built by filling a plain
  twin class with the same slots and setting ``__class__`` (~2x faster than setting slot descriptors, ~4x than
  ``__init__``), inline in the per-ack loop; the registry maps ID -> submission and finds an ack's index as the
  one after the previous ack's; the IDs of a run of 256 formatted once and sliced per batch; an ack that repeats
  the previous one's text after its ID taken with one comparison; the round trip's send/wait path without Python
  calls it does not need (ID, Submission, default timer, ExecResult, loop clock); no enum member lookups.
- Result before/after this work (medians of 5 and 7 runs, same VM; table in docs/protocol.md): round trip p50
  1.26x -> 1.19x; pipelined throughput 0.80x -> 0.86x (10) and 0.80x -> 0.93x (100); CPU per pipelined message
  1.72x -> 1.42x (10) and 1.93x -> 1.28x (100). ``breakdown_us_per_msg`` shows what is left: the ack path without
  building objects (``client_same_without_building_results``) costs about what the bare client's whole receive
  path costs, and building the two values adds ~0.4 us per message.
- Round trip and batches of 10: every microsecond the client spends between reading an ack and writing the next
  message delays the server's next wake-up; measured here (``rtt_amplification``), the round trip grows by
  0.7-2 us per us of such work, and the per-batch work (submission, waiter, wake-up, result tuple) weighs most
  in small batches.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import statistics
import subprocess
import sys
import time

from verdicts import verdict

TARGETS = {"rtt_p50_ratio_max": 1.15, "throughput_ratio_min": 0.9, "cpu_per_msg_ratio_max": 1.5}


# ---------------------------------------------------------------------------------------------------- server
def serve(kind: str) -> None:
    from aioadept.geometry import Pose
    from aioadept.protocol import Ack, LineFramer, Oversize, Status, encode_ack, parse_command
    from aioadept.errors import RemoteProtocolError

    pose = Pose(480.014, -0.038, 709.975, 0.0, 179.995, 0.004)
    t0 = time.monotonic()

    class AckServer(asyncio.Protocol):
        def connection_made(self, transport: asyncio.BaseTransport) -> None:
            self.transport = transport
            self.framer = LineFramer()

        def data_received(self, data: bytes) -> None:
            out = []
            for line in self.framer.feed(data):
                if isinstance(line, Oversize):
                    continue
                try:
                    msg = parse_command(line)
                except RemoteProtocolError as exc:
                    out.append(encode_ack(Ack.error(exc.id, exc.code, exc.message, 0.0, 0.0, pose)))
                    continue
                now = time.monotonic() - t0
                out.append(encode_ack(Ack(msg.id, Status.DONE, now, now, pose)))
            self.transport.write(b"".join(out))

    class EchoServer(asyncio.Protocol):
        def connection_made(self, transport: asyncio.BaseTransport) -> None:
            self.transport = transport

        def data_received(self, data: bytes) -> None:
            self.transport.write(data)

    async def main() -> None:
        loop = asyncio.get_running_loop()
        server = await loop.create_server(AckServer if kind == "ack" else EchoServer, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        print(f"READY port={port}", flush=True)
        # Serve until the parent closes our stdin.
        await loop.run_in_executor(None, sys.stdin.read)
        server.close()

    asyncio.run(main())


def start_server(kind: str) -> tuple[subprocess.Popen, int]:
    proc = subprocess.Popen([sys.executable, __file__, "--serve", kind], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if not line.startswith("READY port="):
        proc.kill()
        raise RuntimeError(f"server did not start: {line!r}")
    return proc, int(line.split("=")[1])


# ---------------------------------------------------------------------------------------------------- clients
class Bare:
    """The baseline: asyncio streams, one write per batch, readuntil per ack, IDs checked against a set."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer
        self.n = 0

    async def batch(self, lines: list[bytes]) -> None:
        ids = set()
        parts = []
        for body in lines:
            self.n += 1
            mid = b"%08x" % self.n
            ids.add(mid)
            parts.append(mid + b":" + body)
        self.writer.write(b"".join(parts))
        readuntil = self.reader.readuntil
        while ids:
            line = await readuntil(b"\r\n")
            ids.remove(line[:8])


def pct(xs: list, q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))]


async def _pipelined(bare_ack: Bare, robot, cmd, line: bytes, quick: bool) -> dict:
    """Pipelined throughput and CPU per message, batches of 10 and of 100, bare client against RobotClient."""
    perf = time.perf_counter
    pipelined: dict = {}
    for size in (10, 100):
        batches = (200 if size == 10 else 30) if quick else (1500 if size == 10 else 200)
        commands = [cmd] * size
        lines = [line] * size
        acc = {"bare": [0.0, 0.0, 0], "client": [0.0, 0.0, 0]}  # wall, cpu, messages
        for _ in range(2):  # warm-up both
            await bare_ack.batch(lines)
            await robot.cmdexec_joined(*commands)
        # Interleaved batch by batch (bare, client, client, bare, ...), so each pair of batches runs under the same
        # load, and the verdict is the median over the pairs of the ratio within each pair: a load spike spoils a
        # few pairs, not the figure (measured block by block, the ratio swung across its goal from run
        # to run, 0.89 then 0.95 on a quiet machine).
        pairs: dict[str, list[float]] = {"throughput": [], "cpu_per_msg": []}
        for i in range(batches):
            t = {}
            for name in (("bare", "client") if i % 2 == 0 else ("client", "bare")):
                w, c = perf(), time.process_time()
                if name == "bare":
                    await bare_ack.batch(lines)
                else:
                    await robot.cmdexec_joined(*commands)
                t[name] = (perf() - w, time.process_time() - c)
                acc[name][0] += t[name][0]
                acc[name][1] += t[name][1]
                acc[name][2] += size
            pairs["throughput"].append(t["bare"][0] / t["client"][0])
            if t["bare"][1] > 0:
                pairs["cpu_per_msg"].append(t["client"][1] / t["bare"][1])
        pipelined[str(size)] = {
            name: {"msgs_per_s": a[2] / a[0], "cpu_us_per_msg": a[1] / a[2] * 1e6, "messages": a[2]}
            for name, a in acc.items()}
        pipelined[str(size)]["pairs"] = len(pairs["throughput"])
        pipelined[str(size)]["ratio_median_of_pairs"] = {k: round(statistics.median(v), 3) for k, v in pairs.items()}
    return pipelined


async def _amplification(bare_ack: Bare, line: bytes, per_round: int) -> dict:
    """The bare client's RTT when it does extra CPU work before each write (busy loop), to show how much a
    microsecond of client work costs in round trip on this machine (cross-process wake-ups)."""
    perf = time.perf_counter
    amplification = {}
    for spin_us in (0, 20):
        xs: list = []
        for _ in range(per_round * 2):
            t = perf()
            end = t + spin_us * 1e-6
            while perf() < end:
                pass
            await bare_ack.batch([line])
            xs.append(perf() - t)
        amplification[f"bare_plus_{spin_us}us_work_rtt_p50_us"] = pct(xs, 0.5) * 1e6
    return amplification


async def measure(port_ack: int, port_echo: int, quick: bool) -> dict:
    from aioadept.client import RobotClient
    from aioadept.commands import Skill

    loop = asyncio.get_running_loop()
    bare_ack = Bare(*await asyncio.open_connection("127.0.0.1", port_ack))
    bare_echo = Bare(*await asyncio.open_connection("127.0.0.1", port_echo))
    robot = RobotClient("127.0.0.1", port_ack, ack_timeout_s=10.0, max_pending=None)  # its own ack server: no queue
    await robot.connect()
    cmd = Skill("noop")
    line = b"noop\r\n"
    perf = time.perf_counter

    # --- round trip of one instant skill
    rounds, per_round = (4, 250) if quick else (12, 500)
    rtt = {"bare": [], "client": [], "echo": []}

    async def rtt_bare(b: Bare, out: list) -> None:
        for _ in range(per_round):
            t = perf()
            await b.batch([line])
            out.append(perf() - t)

    async def rtt_client(out: list) -> None:
        cmdexec = robot.cmdexec
        for _ in range(per_round):
            t = perf()
            await cmdexec(cmd)
            out.append(perf() - t)

    await rtt_bare(bare_ack, [])  # warm-up
    await rtt_client([])
    await rtt_bare(bare_echo, [])
    for _ in range(rounds):
        await rtt_bare(bare_ack, rtt["bare"])
        await rtt_client(rtt["client"])
        await rtt_bare(bare_echo, rtt["echo"])

    rtt_us = {k: {"p50": pct(v, 0.5) * 1e6, "p99": pct(v, 0.99) * 1e6, "n": len(v)} for k, v in rtt.items()}

    pipelined = await _pipelined(bare_ack, robot, cmd, line, quick)
    amplification = await _amplification(bare_ack, line, per_round)

    await robot.close()
    for b in (bare_ack, bare_echo):
        b.writer.close()
        await b.writer.wait_closed()
    assert robot.stats.late_acks == robot.stats.unknown_acks == robot.stats.bad_lines == 0

    ratios = {
        "rtt_p50": rtt_us["client"]["p50"] / rtt_us["bare"]["p50"],
        "rtt_p99": rtt_us["client"]["p99"] / rtt_us["bare"]["p99"],
    }
    for size, d in pipelined.items():  # the median of the per-pair ratios: steadier than the pooled one
        ratios[f"throughput_{size}"] = d["ratio_median_of_pairs"]["throughput"]
        ratios[f"cpu_per_msg_{size}"] = d["ratio_median_of_pairs"]["cpu_per_msg"]
    met = {
        "rtt_p50": ratios["rtt_p50"] <= TARGETS["rtt_p50_ratio_max"],
        "throughput": min(ratios["throughput_10"], ratios["throughput_100"]) >= TARGETS["throughput_ratio_min"],
        "cpu_per_msg": max(ratios["cpu_per_msg_10"], ratios["cpu_per_msg_100"]) <= TARGETS["cpu_per_msg_ratio_max"],
    }
    return {"rtt_us": rtt_us, "pipelined": pipelined, "ratios": ratios, "targets": TARGETS, "met": met,
            "rtt_amplification": amplification, "breakdown_us_per_msg": await breakdown(),
            "loop": type(loop).__module__ + "." + type(loop).__name__}


async def breakdown(n: int = 100, batches: int = 300) -> dict:
    """CPU per message of each stage, in process and without sockets (the profile behind the ratios)."""
    import aioadept.client.registry as client_mod
    from aioadept.client import ClientState, RobotClient
    from aioadept.commands import Skill
    from aioadept.geometry import Pose
    from aioadept.protocol import Ack, LineFramer, Status, encode_ack

    loop = asyncio.get_running_loop()
    tail = encode_ack(Ack("XXXXXXXX", Status.DONE, 1.0, 1.0, Pose(480.014, -0.038, 709.975, 0.0, 179.995, 0.004)))[8:]
    robot = RobotClient(max_pending=None)
    robot._loop, robot._write, robot._state = loop, (lambda data: None), ClientState.CONNECTED
    calls = Skill("noop").calls() * n
    per_msg = 1e6 / (n * batches)
    out: dict = {}

    def clock(name: str, fn) -> None:
        c = time.process_time()
        fn()
        out[name] = min(out.get(name, 1e9), (time.process_time() - c) * per_msg)

    for _ in range(3):
        subs: list = []
        clock("client_send", lambda subs=subs: subs.extend(robot._send(calls) for _ in range(batches)))
        replies = [b"".join([m.encode() + tail for m in s.ids]) for s in subs]
        framer = LineFramer(1024)
        clock("client_framing", lambda framer=framer, replies=replies: [framer.feed(r) for r in replies])
        clock("client_framing_parse_route_build", lambda replies=replies: [robot._feed(r, 0.0) for r in replies])
        for s in subs:
            s.cancel()
        subs = [robot._send(calls) for _ in range(batches)]
        replies = [b"".join([m.encode() + tail for m in s.ids]) for s in subs]
        saved = client_mod._make_result, client_mod._RESULT_TWIN
        # ablation: no MessageResult objects (the inline build is off without the twin; the reader builds Acks)
        client_mod._make_result = lambda *a: a
        client_mod._RESULT_TWIN = None
        try:
            clock("client_same_without_building_results",
                  lambda replies=replies: [robot._feed(r, 0.0) for r in replies])
        finally:
            client_mod._make_result, client_mod._RESULT_TWIN = saved
        for s in subs:
            s.cancel()

        def bare_send() -> None:
            for r in range(batches):
                ids, parts = set(), []
                for k in range(n):
                    mid = b"%08x" % (r * n + k)
                    ids.add(mid)
                    parts.append(mid + b":noop\r\n")
                b"".join(parts)
        clock("bare_send", bare_send)
        blobs = [b"".join([b"%08x" % (r * n + k) + tail for k in range(n)]) for r in range(batches)]
        reader = asyncio.StreamReader()
        c = time.process_time()
        for r in range(batches):
            reader.feed_data(blobs[r])
            ids = {b"%08x" % (r * n + k) for k in range(n)}
            for _ in range(n):
                ids.remove((await reader.readuntil(b"\r\n"))[:8])
        out["bare_readuntil_and_match"] = min(out.get("bare_readuntil_and_match", 1e9),
                                              (time.process_time() - c) * per_msg)
    return {k: round(v, 2) for k, v in out.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--serve", choices=["ack", "echo"], help=argparse.SUPPRESS)
    ap.add_argument("--loop", choices=["asyncio", "uvloop"], default="asyncio", help="client event loop")
    ap.add_argument("--quick", action="store_true", help="fewer iterations (a smoke run)")
    ap.add_argument("--repeat", type=int, default=1, metavar="N",
                    help="measure N times against the same servers; the targets are judged on median ratios")
    args = ap.parse_args(argv)
    if args.serve:
        serve(args.serve)
        return 0
    servers = [start_server("ack"), start_server("echo")]
    try:
        factory = asyncio.new_event_loop
        if args.loop == "uvloop":
            import uvloop
            factory = uvloop.new_event_loop
        load_before = os.getloadavg()
        runs = []
        for _ in range(max(1, args.repeat)):
            with asyncio.Runner(loop_factory=factory) as runner:
                runs.append(runner.run(measure(servers[0][1], servers[1][1], args.quick)))
        load_after = os.getloadavg()
    finally:
        for proc, _ in servers:
            assert proc.stdin is not None
            proc.stdin.close()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
    machine = {"python": platform.python_version(), "cpus": os.cpu_count(),
               "loadavg_1_5_15_before": [round(x, 2) for x in load_before],
               "loadavg_1_5_15_after": [round(x, 2) for x in load_after]}
    if len(runs) == 1:
        result = runs[0]
        result["machine"] = machine
    else:
        med = {k: statistics.median(r["ratios"][k] for r in runs) for k in runs[0]["ratios"]}
        result = {
            "median_ratios": med,
            "ratios_per_run": [r["ratios"] for r in runs],
            "targets": TARGETS,
            "met_by_median": {
                "rtt_p50": med["rtt_p50"] <= TARGETS["rtt_p50_ratio_max"],
                "throughput": min(med["throughput_10"], med["throughput_100"]) >= TARGETS["throughput_ratio_min"],
                "cpu_per_msg": max(med["cpu_per_msg_10"], med["cpu_per_msg_100"]) <= TARGETS["cpu_per_msg_ratio_max"],
            },
            "machine": machine,
            "runs": runs,
        }
    result["verdicts"] = client_verdicts(runs)
    print(json.dumps(result, indent=2))
    return 0


def client_verdicts(runs: list[dict]) -> list[dict]:
    """The three goals of TARGETS, each on the median over the runs (one run: its own figures)."""
    def med(get):  # the median over runs of one figure
        return statistics.median(get(r) for r in runs)

    worst_tp = min((10, 100), key=lambda s: med(lambda r: r["ratios"][f"throughput_{s}"]))
    worst_cpu = max((10, 100), key=lambda s: med(lambda r: r["ratios"][f"cpu_per_msg_{s}"]))
    rtt = med(lambda r: r["ratios"]["rtt_p50"])
    tp = med(lambda r: r["ratios"][f"throughput_{worst_tp}"])
    cpu = med(lambda r: r["ratios"][f"cpu_per_msg_{worst_cpu}"])
    return [
        verdict("rtt p50, cmdexec vs bare client", med(lambda r: r["rtt_us"]["client"]["p50"]),
                med(lambda r: r["rtt_us"]["bare"]["p50"]), unit="us", ratio=rtt,
                goal=f"ratio <= {TARGETS['rtt_p50_ratio_max']}", passed=rtt <= TARGETS["rtt_p50_ratio_max"]),
        verdict(f"pipelined throughput, batches of {worst_tp} (worse size)",
                med(lambda r: r["pipelined"][str(worst_tp)]["client"]["msgs_per_s"]),
                med(lambda r: r["pipelined"][str(worst_tp)]["bare"]["msgs_per_s"]), unit="msg/s", ratio=tp,
                goal=f"ratio >= {TARGETS['throughput_ratio_min']}", passed=tp >= TARGETS["throughput_ratio_min"]),
        verdict(f"client CPU per message, batches of {worst_cpu} (worse size)",
                med(lambda r: r["pipelined"][str(worst_cpu)]["client"]["cpu_us_per_msg"]),
                med(lambda r: r["pipelined"][str(worst_cpu)]["bare"]["cpu_us_per_msg"]), unit="us", ratio=cpu,
                goal=f"ratio <= {TARGETS['cpu_per_msg_ratio_max']}", passed=cpu <= TARGETS["cpu_per_msg_ratio_max"]),
    ]


if __name__ == "__main__":
    sys.exit(main())
