"""Stop latency of ``aioadept sim`` under a flood, and ``here`` latency while another client's arm moves.

Two safety promises, measured against their baselines in the same run (docs/security.md, "Safety promises"):

- **stop**: a mover client starts a long J1 move and a ``break``; a stopper client (its own connection) writes
  ``stop``. Latency = stopper's write -> the mover receives its break's ``aborted`` ack, which the server writes the
  moment it has read and acted on the stop (deceleration is not included; ``stop_done`` adds it). Baseline: no
  flood. Flood: three clients in a separate process write ``here`` lines as fast as the server takes them (and read
  their acks). The promise is p95 <= 100 ms under the flood.
- **here**: 50 clients each send ``here`` once, at rest (baseline) and while another client's arm moves with a
  ``break`` pending; p50/p95 round trip.
- **stuck peers**, on both servers (the Python sim and the shipped V+ server on the emulator): the stop
  latency above with one client that pipelines ``here`` lines and never reads its acks (it reconnects whenever the
  server drops it, so the attack lasts the whole run), and with every client slot held by idle peers while the
  stop comes through the stop port (a fresh connection per stop). Baseline: the same server, a stop from an
  admitted client with nobody misbehaving. The promise is p95 <= 100 ms.
- **stop-port crowds**, on both servers, every main-port slot held: a newcomer's stop through the stop
  port (connecting again whenever it is turned away; ``aioadept.testing.crowds.stop_through``, from its first try
  to its ``done``, the arm moving at 10 %) while a crowd process holds the stop port: 4 monitors polling ``here``
  every 0.5 s, a storm of 8 loops of short connections (connect, ``here``, 0.5 s, close), 6 slowloris peers
  reconnecting at once. Baseline: the same stop with nobody on the stop port. The promise is p95 <= 100 ms.

The sim and the flooders are child processes on 127.0.0.1 (port 0, ``READY`` line). Prints one JSON object.

Usage: ``python benchmarks/bench_safety.py [--trials 30]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import statistics
import sys
from pathlib import Path

from verdicts import verdict

from aioadept.testing.crowds import stop_through

CROWDS = {"monitors": 4, "storm": 8, "slowloris": 6}

FLOODER = r"""
import asyncio, sys
port, n = int(sys.argv[1]), int(sys.argv[2])
async def one(k):
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    async def drain_acks():
        while await reader.read(65536):
            pass
    t = asyncio.create_task(drain_acks())
    batch = b"".join(b"%07x%d:here\r\n" % (i, k) for i in range(100))
    try:
        while True:
            writer.write(batch)
            await writer.drain()
    except (OSError, asyncio.CancelledError):
        pass
async def main():
    tasks = [asyncio.create_task(one(k)) for k in range(n)]
    print("READY", flush=True)
    await asyncio.gather(*tasks, return_exceptions=True)
asyncio.run(main())
"""


NOREAD = r"""
import asyncio, socket, sys
port = int(sys.argv[1])
async def main():
    loop = asyncio.get_running_loop()
    n = 0
    print("READY", flush=True)
    while True:
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        sock.setblocking(False)
        try:
            await loop.sock_connect(sock, ("127.0.0.1", port))
        except OSError:
            await asyncio.sleep(0.05)
            continue
        _, writer = await asyncio.open_connection(sock=sock)
        # never reads: pipelines until its own sends back up (the server has stopped reading it, or dropped it),
        # then holds the connection; when the server drops it, it comes back and does it again
        while not writer.is_closing():
            if writer.transport.get_write_buffer_size() == 0:
                writer.write(b"".join(b"%08x:here\r\n" % (0x10000000 + (n + i) % 0x70000000) for i in range(200)))
                n += 200
            await asyncio.sleep(0.01)
asyncio.run(main())
"""


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(round(q * (len(s) - 1))))]


def summary(ms: list[float]) -> dict:
    return {"n": len(ms), "p50_ms": round(statistics.median(ms), 2), "p95_ms": round(pct(ms, 0.95), 2),
            "max_ms": round(max(ms), 2)}


class Conn:
    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer

    @classmethod
    async def open(cls, port: int) -> Conn:
        return cls(*await asyncio.open_connection("127.0.0.1", port))

    async def until(self, mid: bytes) -> bytes:
        while True:
            line = await self.reader.readuntil(b"\r\n")
            if line.startswith(mid + b":"):
                return line


async def start(argv: list[str]) -> tuple[asyncio.subprocess.Process, str]:
    proc = await asyncio.create_subprocess_exec(*argv, stdout=asyncio.subprocess.PIPE,
                                                stderr=asyncio.subprocess.DEVNULL)
    assert proc.stdout is not None
    line = ""
    async with asyncio.timeout(30):
        while not line.startswith("READY"):  # the V+ server prints its console first
            line = (await proc.stdout.readline()).decode()
            if not line:
                proc.kill()
                raise RuntimeError("child did not start")
    asyncio.get_running_loop().create_task(_drain(proc.stdout))  # its later console lines must not block it
    return proc, line


async def _drain(stream: asyncio.StreamReader) -> None:
    while await stream.readline():
        pass


async def stop_trials(port: int, trials: int, stop_port: int | None = None) -> tuple[list[float], list[float]]:
    """``stop_port``: each stop on a fresh connection to that port (the stop port) instead of an admitted client."""
    loop = asyncio.get_running_loop()
    mover, stopper = await Conn.open(port), None if stop_port else await Conn.open(port)
    acted, done, late = [], [], []
    for i in range(trials):
        target = 150 if i % 2 == 0 else -150
        m, b, s = b"%08x" % (3 * i + 1), b"%08x" % (3 * i + 2), b"%08x" % (3 * i + 3)
        mover.writer.write(m + b":move_joints:%d,-90,180,0,90,0\r\n" % target + b + b":break\r\n")
        await asyncio.wait_for(mover.until(m), 30)  # a server that lost the slot must fail the bench, not hang it
        await asyncio.sleep(0.05)  # the arm is moving, the break waits
        t0 = loop.time()
        via = stopper if stop_port is None else await asyncio.wait_for(Conn.open(stop_port), 30)
        via.writer.write(s + b":stop\r\n")
        line = await asyncio.wait_for(mover.until(b), 30)
        t_break = loop.time()
        await asyncio.wait_for(via.until(s), 30)
        t_done = loop.time()
        if via is not stopper:
            via.writer.close()
        # A break that completed instead of being aborted: the stop came too late to act on the motion; count
        # it at the time the stop was answered (an underestimate of how late it really was).
        acted.append(((t_break if b":aborted:" in line else t_done) - t0) * 1e3)
        if b":aborted:" not in line:
            late.append(i)
        done.append((t_done - t0) * 1e3)
    for c in (mover, stopper):
        if c is not None:
            c.writer.close()
    if late:
        print(f"{len(late)} of {trials} stops arrived after the motion had completed", file=sys.stderr)
    return acted, done


async def here_trial(port: int, moving: bool, clients: int = 50) -> list[float]:
    loop = asyncio.get_running_loop()
    pollers = [await Conn.open(port) for _ in range(clients)]
    mover = await Conn.open(port)
    if moving:
        mover.writer.write(b"0000aaa1:move_joints:150,-90,180,0,90,0\r\n0000aaa2:break\r\n")
        await asyncio.wait_for(mover.until(b"0000aaa1"), 30)

    async def one(c: Conn, k: int) -> float:
        mid = b"0001%04d" % k  # never 00000000, the reserved ID
        t0 = loop.time()
        c.writer.write(mid + b":here\r\n")
        await c.until(mid)
        return (loop.time() - t0) * 1e3

    out = list(await asyncio.gather(*(one(c, k) for k, c in enumerate(pollers))))
    if moving:
        await mover.until(b"0000aaa2")
        # back home for the next trial
        mover.writer.write(b"0000aaa3:move_joints:0,-90,180,0,90,0\r\n0000aaa4:break\r\n")
        await mover.until(b"0000aaa4")
    for c in (*pollers, mover):
        c.writer.close()
    return out


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def crowd_trials(port: int, sport: int, trials: int, kind: str | None) -> list[float]:
    """A newcomer's stop through the stop port, ms from its first try to its ``done``, with a crowd process of
    ``kind`` on the stop port (None: nobody). The mover on ``port`` moves J1 back and forth meanwhile."""
    crowd = None
    if kind is not None:
        crowd, _ = await start([sys.executable, "-m", "aioadept.testing.crowds", kind, "127.0.0.1", str(sport),
                                str(CROWDS[kind])])
        await asyncio.sleep(1.5)  # past the stop port's idle time: the crowd has settled in
    out = []
    try:
        await asyncio.sleep(0.3)  # the last mover's slot is free again
        mover = await Conn.open(port)
        for i in range(trials):
            m = b"%08x" % (0x30000001 + i)
            # at 10 % (set_speed is for the next motion only) the arm is at rest moments after the stop, so the
            # done ack times the stop's way in, not the braking
            mover.writer.write(b"%08x:set_speed:10\r\n" % (0x31000001 + i) + m
                               + b":move_joints:%d,-90,180,0,90,0\r\n" % (150 if i % 2 == 0 else -150))
            await asyncio.wait_for(mover.until(m), 30)
            await asyncio.sleep(0.05)  # moving
            out.append(await stop_through("127.0.0.1", sport, within_s=30.0) * 1e3)
        mover.writer.close()
    finally:
        if crowd is not None:
            crowd.kill()
            await crowd.wait()
    return out


async def stuck_peers(aioadept: str, backend: str, trials: int) -> dict:
    """Stop latency on one backend: baseline, one non-reading client, every slot held (stop via the stop port)."""
    root = Path(__file__).resolve().parents[1] / "vplus"
    port, sport = _free_port(), _free_port()
    if backend == "python":
        argv = [aioadept, "sim", "--port", str(port), "--stop-port", str(sport), "--max-clients", "4"]
        slots = 4
    else:
        argv = [aioadept, "sim", "--vplus", *(str(root / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")),
                "--run", "rs.main", "--map-port", f"1234={port}", "--map-port", f"1235={sport}"]
        slots = 10  # rs.maxcli
    proc, _ = await start([*argv, "--state-endpoint", "none"])
    out: dict = {}
    try:
        await asyncio.sleep(0.5)  # the V+ server opens its stop port just after READY
        out["baseline"], _ = await stop_trials(port, trials)
        flood, _ = await start([sys.executable, "-c", NOREAD, str(port)])
        try:
            await asyncio.sleep(1.0)  # its acks have backed up
            out["one_not_reading"], _ = await stop_trials(port, trials)
        finally:
            flood.kill()
            await flood.wait()
        await asyncio.sleep(0.5)
        held = [await Conn.open(port) for _ in range(slots - 1)]  # the mover takes the last slot
        try:
            out["every_slot_held"], _ = await stop_trials(port, trials, stop_port=sport)
            out["stop_port_nobody"] = await crowd_trials(port, sport, trials, None)
            for kind in CROWDS:
                out[f"stop_port_{kind}"] = await crowd_trials(port, sport, trials, kind)
        finally:
            for c in held:
                c.writer.close()
    finally:
        proc.terminate()
        await proc.wait()
    return out


async def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=30)
    ap.add_argument("--flooders", type=int, default=3)
    ap.add_argument("--stuck-trials", type=int, default=20, dest="stuck_trials")
    args = ap.parse_args()
    aioadept = str(Path(sys.executable).with_name("aioadept"))
    proc, ready = await start([aioadept, "sim", "--port", "0", "--state-endpoint", "none", "--max-clients", "64"])
    port = int(dict(f.split("=", 1) for f in ready.split()[1:])["port"])
    result: dict = {"machine": {"python": platform.python_version(), "cpus": os.cpu_count()}}
    try:
        base_acted, base_done = await stop_trials(port, args.trials)
        here_rest = []
        here_moving = []
        for _ in range(3):
            here_rest += await here_trial(port, moving=False)
            here_moving += await here_trial(port, moving=True)
        flood, _ = await start([sys.executable, "-c", FLOODER, str(port), str(args.flooders)])
        try:
            await asyncio.sleep(0.5)  # the flood is on
            flood_acted, flood_done = await stop_trials(port, args.trials)
        finally:
            flood.kill()
            await flood.wait()
    finally:
        proc.terminate()
        await proc.wait()
    result["stop_acted_baseline"] = summary(base_acted)
    result["stop_acted_flood"] = summary(flood_acted)
    result["stop_done_baseline"] = summary(base_done)
    result["stop_done_flood"] = summary(flood_done)
    result["stop_acted_ratio_p95"] = round(pct(flood_acted, 0.95) / pct(base_acted, 0.95), 2)
    result["stop_acted_flood_p95_within_100ms"] = pct(flood_acted, 0.95) <= 100.0
    result["here_50_at_rest"] = summary(here_rest)
    result["here_50_while_moving"] = summary(here_moving)
    result["here_ratio_p50"] = round(statistics.median(here_moving) / statistics.median(here_rest), 2)
    stuck = {b: await stuck_peers(aioadept, b, args.stuck_trials) for b in ("python", "vplus")}
    result["stuck_peers"] = {b: {k: summary(v) for k, v in d.items()} for b, d in stuck.items()}
    result["verdicts"] = [
        verdict("stop acted p95, 3-client flood vs no flood", pct(flood_acted, 0.95), pct(base_acted, 0.95),
                unit="ms", goal="figure <= 100 ms", passed=pct(flood_acted, 0.95) <= 100.0),
        verdict("here p50, 50 clients, arm moving vs at rest", statistics.median(here_moving),
                statistics.median(here_rest), unit="ms"),
    ]
    for b, d in stuck.items():
        for case, label in (("one_not_reading", "one client not reading"), ("every_slot_held", "every slot held")):
            p95 = pct(d[case], 0.95)
            result["verdicts"].append(verdict(f"{b}: stop acted p95, {label} vs nobody", p95,
                                              pct(d["baseline"], 0.95), unit="ms", goal="figure <= 100 ms",
                                              passed=p95 <= 100.0))
        for kind, n in CROWDS.items():
            p95 = pct(d[f"stop_port_{kind}"], 0.95)
            result["verdicts"].append(verdict(f"{b}: newcomer's stop p95, {n} {kind} on the stop port vs nobody", p95,
                                              pct(d["stop_port_nobody"], 0.95), unit="ms", goal="figure <= 100 ms",
                                              passed=p95 <= 100.0))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    asyncio.run(main())
