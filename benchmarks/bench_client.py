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
absolute numbers, the ratios RobotClient / bare, and the issue's targets.
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


async def measure(port_ack: int, port_echo: int, quick: bool) -> dict:
    from aioadept.client import RobotClient
    from aioadept.commands import Skill

    loop = asyncio.get_running_loop()
    bare_ack = Bare(*await asyncio.open_connection("127.0.0.1", port_ack))
    bare_echo = Bare(*await asyncio.open_connection("127.0.0.1", port_echo))
    robot = RobotClient("127.0.0.1", port_ack, ack_timeout_s=10.0)
    await robot.connect()
    cmd = Skill("noop")
    line = b"noop\r\n"
    perf = time.perf_counter

    # --- round trip of one instant skill
    rounds, per_round = (4, 250) if quick else (10, 500)
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

    def pct(xs: list, q: float) -> float:
        xs = sorted(xs)
        return xs[min(len(xs) - 1, int(q * len(xs)))]

    rtt_us = {k: {"p50": pct(v, 0.5) * 1e6, "p99": pct(v, 0.99) * 1e6, "n": len(v)} for k, v in rtt.items()}

    # --- pipelined throughput and CPU per message
    pipelined: dict = {}
    for size in (10, 100):
        batches = (200 if size == 10 else 30) if quick else (600 if size == 10 else 80)
        commands = [cmd] * size
        lines = [line] * size
        acc = {"bare": [0.0, 0.0, 0], "client": [0.0, 0.0, 0]}  # wall, cpu, messages
        for _ in range(2):  # warm-up both
            await bare_ack.batch(lines)
            await robot.cmdexec_joined(*commands)
        for _ in range(rounds):
            for name in ("bare", "client"):
                w, c = perf(), time.process_time()
                if name == "bare":
                    for _ in range(batches // rounds):
                        await bare_ack.batch(lines)
                else:
                    for _ in range(batches // rounds):
                        await robot.cmdexec_joined(*commands)
                acc[name][0] += perf() - w
                acc[name][1] += time.process_time() - c
                acc[name][2] += (batches // rounds) * size
        pipelined[str(size)] = {
            name: {"msgs_per_s": a[2] / a[0], "cpu_us_per_msg": a[1] / a[2] * 1e6, "messages": a[2]}
            for name, a in acc.items()}

    await robot.close()
    for b in (bare_ack, bare_echo):
        b.writer.close()
        await b.writer.wait_closed()
    assert robot.stats.late_acks == robot.stats.unknown_acks == robot.stats.bad_lines == 0

    ratios = {
        "rtt_p50": rtt_us["client"]["p50"] / rtt_us["bare"]["p50"],
        "rtt_p99": rtt_us["client"]["p99"] / rtt_us["bare"]["p99"],
    }
    for size, d in pipelined.items():
        ratios[f"throughput_{size}"] = d["client"]["msgs_per_s"] / d["bare"]["msgs_per_s"]
        ratios[f"cpu_per_msg_{size}"] = d["client"]["cpu_us_per_msg"] / d["bare"]["cpu_us_per_msg"]
    met = {
        "rtt_p50": ratios["rtt_p50"] <= TARGETS["rtt_p50_ratio_max"],
        "throughput": min(ratios["throughput_10"], ratios["throughput_100"]) >= TARGETS["throughput_ratio_min"],
        "cpu_per_msg": max(ratios["cpu_per_msg_10"], ratios["cpu_per_msg_100"]) <= TARGETS["cpu_per_msg_ratio_max"],
    }
    return {"rtt_us": rtt_us, "pipelined": pipelined, "ratios": ratios, "targets": TARGETS, "met": met,
            "loop": type(loop).__module__ + "." + type(loop).__name__}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--serve", choices=["ack", "echo"], help=argparse.SUPPRESS)
    ap.add_argument("--loop", choices=["asyncio", "uvloop"], default="asyncio", help="client event loop")
    ap.add_argument("--quick", action="store_true", help="fewer iterations (a smoke run)")
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
        with asyncio.Runner(loop_factory=factory) as runner:
            result = runner.run(measure(servers[0][1], servers[1][1], args.quick))
    finally:
        for proc, _ in servers:
            assert proc.stdin is not None
            proc.stdin.close()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
    result["machine"] = {"python": platform.python_version(), "cpus": os.cpu_count()}
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
