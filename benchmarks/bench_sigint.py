"""Benchmark: Ctrl-C -> stop latency of the command-line apps, with a plain stop as baseline.

    .venv/bin/python benchmarks/bench_sigint.py [--rounds N] [--signal INT|TERM|HUP]

Each round starts ``aioadept send`` as a real process, waits until its command is under way, sends it SIGINT
(``os.kill``) and measures, on the robot's side:

- ``sigint_to_stop_on_wire_ms``: SIGINT sent -> the ``stop`` line read by a bare robot server in this process (it
  acks every command at once and holds ``break``, a motion that goes on). Both ends use the system-wide monotonic
  clock. The issue's target: within 100 ms.
- ``sigint_to_exit_ms``: SIGINT sent -> the process has exited (stop acked, connection closed, one line printed).
- ``sigint_to_rest_ms``: against ``aioadept sim`` (real time, a joint move at 5 %): SIGINT sent -> the first
  state sample (100 Hz) with the arm at rest; includes the deceleration.

Baselines measured in the same run, same servers:

- ``stop_roundtrip_ms``: ``RobotClient.stop()`` from this process to the bare server (write -> ack).
- ``stop_call_to_rest_ms``: ``RobotClient.stop()`` from this process during the same sim motion -> first state
  sample at rest.

Prints one JSON object: p50/p95/max per quantity and the ratios of the medians (signal path / direct stop). The
difference is the cost of the signal path: signal delivery, the loop's wake-up, and a second process.
``--signal HUP`` (or TERM) sends that signal instead (a closed terminal): the apps treat every
stop signal alike, so the same keys hold its figures; ``signal`` in the JSON says which one was sent.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import statistics
import sys
import time

from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import Subscriber
from aioadept.client import RobotClient
from aioadept.commands import MoveRelJoints, SetSpeed
from aioadept.geometry import Pose
from aioadept.protocol import Ack, LineFramer, Status, encode_ack, parse_command
from aioadept.testing.nodes import running_node

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from verdicts import verdict  # noqa: E402

AIOADEPT = [sys.executable, "-m", "aioadept"]
POSE = Pose(480.0, 0.0, 710.0, 0.0, 180.0, 0.0)
SIGNAL = signal.SIGINT
"""The signal sent to the app (``--signal``)."""


def _stats(xs: list[float]) -> dict[str, float]:
    s = sorted(xs)
    return {"n": len(s), "p50": round(statistics.median(s), 3), "p95": round(s[min(len(s) - 1, int(0.95 * len(s)))], 3),
            "max": round(s[-1], 3)}


class BareServer:
    """Acks everything ``done`` at once, holds ``break``; on ``stop``: the held break ``aborted``, the stop ``done``."""

    def __init__(self) -> None:
        self.break_seen = asyncio.Event()
        self.stop_t: float | None = None

    async def serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        framer = LineFramer()
        held: list[str] = []
        try:
            while data := await reader.read(4096):
                t = time.monotonic()
                for line in framer.feed(data):
                    msg = parse_command(line)
                    if msg.skill == "break":
                        held.append(msg.id)
                        self.break_seen.set()
                    elif msg.skill == "stop":
                        if self.stop_t is None:
                            self.stop_t = t
                        for mid in held:
                            writer.write(encode_ack(Ack(mid, Status.ABORTED, 1.0, 1.0, POSE, ())))
                        held.clear()
                        writer.write(encode_ack(Ack(msg.id, Status.DONE, 1.0, 1.0, POSE, ())))
                    else:
                        writer.write(encode_ack(Ack(msg.id, Status.DONE, 1.0, 1.0, POSE, ())))
        except ConnectionError:
            pass
        finally:
            writer.close()


async def _spawn_send(port: int, *skills: str) -> asyncio.subprocess.Process:
    return await asyncio.create_subprocess_exec(*AIOADEPT, "send", "--port", str(port), *skills,
                                                stdout=asyncio.subprocess.DEVNULL, stderr=asyncio.subprocess.PIPE)


async def wire_rounds(rounds: int) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {"sigint_to_stop_on_wire_ms": [], "sigint_to_exit_ms": [], "stop_roundtrip_ms": []}
    for _ in range(rounds):
        bare = BareServer()
        server = await asyncio.start_server(bare.serve, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        async with server:
            proc = await _spawn_send(port, "move_rel_joints:10,0,0,0,0,0", "break")
            await asyncio.wait_for(bare.break_seen.wait(), 30)
            t0 = time.monotonic()
            os.kill(proc.pid, SIGNAL)
            await asyncio.wait_for(proc.wait(), 30)
            t_exit = time.monotonic()
            assert proc.returncode == 130, proc.returncode
            assert bare.stop_t is not None
            out["sigint_to_stop_on_wire_ms"].append((bare.stop_t - t0) * 1e3)
            out["sigint_to_exit_ms"].append((t_exit - t0) * 1e3)
            # Baseline: a plain stop round trip from this process to the same server.
            async with RobotClient("127.0.0.1", port) as rc:
                t1 = time.monotonic()
                await rc.stop()
                out["stop_roundtrip_ms"].append((time.monotonic() - t1) * 1e3)
    return out


async def _until(sub: Subscriber, pred, timeout_s: float = 30.0) -> float:
    async with asyncio.timeout(timeout_s):
        while True:
            _t, payload = await sub.recv()
            if pred(RobotState.from_bytes(payload)):
                return time.monotonic()


async def sim_rounds(rounds: int) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {"sigint_to_rest_ms": [], "stop_call_to_rest_ms": []}
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0") as sim:
        port = int(sim.ready["port"])
        sub = Subscriber(sim.ready["state"], topics=[ROBOT_STATE_TOPIC])
        try:
            await _until(sub, lambda st: True)
            for k in range(rounds):
                sign = 1 if k % 2 == 0 else -1  # back and forth, so the arm stays in its range
                # Through a process and SIGINT.
                proc = await _spawn_send(port, "set_speed:5", f"move_rel_joints:{30 * sign},0,0,0,0,0", "break")
                await _until(sub, lambda st: st.in_motion and st.speed_pct == 5)
                t0 = time.monotonic()
                os.kill(proc.pid, SIGNAL)
                out["sigint_to_rest_ms"].append((await _until(sub, lambda st: not st.in_motion) - t0) * 1e3)
                await asyncio.wait_for(proc.wait(), 30)
                # Baseline: the same motion, stopped by RobotClient.stop() in this process.
                async with RobotClient("127.0.0.1", port) as rc:
                    moving = asyncio.ensure_future(rc.cmdexec(SetSpeed(5), MoveRelJoints([30 * sign, 0, 0, 0, 0, 0])))
                    await _until(sub, lambda st: st.in_motion and st.speed_pct == 5)
                    t1 = time.monotonic()
                    stop = asyncio.ensure_future(rc.stop())
                    out["stop_call_to_rest_ms"].append((await _until(sub, lambda st: not st.in_motion) - t1) * 1e3)
                    await stop
                    await asyncio.gather(moving, return_exceptions=True)
        finally:
            sub.close()
    return out


async def main(rounds: int) -> dict:
    wire = await wire_rounds(rounds)
    sim = await sim_rounds(rounds)
    data = {**wire, **sim}
    stats = {k: _stats(v) for k, v in data.items()}
    return {
        "benchmark": "sigint_to_stop",
        "rounds": rounds,
        "signal": SIGNAL.name,
        "cpu_count": os.cpu_count(),
        "stats_ms": stats,
        "ratios_of_medians": {
            "sigint_to_stop_on_wire / stop_roundtrip": round(
                stats["sigint_to_stop_on_wire_ms"]["p50"] / stats["stop_roundtrip_ms"]["p50"], 2),
            "sigint_to_rest / stop_call_to_rest": round(
                stats["sigint_to_rest_ms"]["p50"] / stats["stop_call_to_rest_ms"]["p50"], 2),
        },
        "target": "SIGINT -> stop on the wire within 100 ms",
        "target_met_p95": stats["sigint_to_stop_on_wire_ms"]["p95"] < 100.0,
        "verdicts": [
            verdict("SIGINT -> stop on the wire p95 vs stop() round trip p95", stats["sigint_to_stop_on_wire_ms"]["p95"],
                    stats["stop_roundtrip_ms"]["p95"], unit="ms", goal="figure < 100 ms",
                    passed=stats["sigint_to_stop_on_wire_ms"]["p95"] < 100.0),
            verdict("SIGINT -> arm at rest p50 vs stop() -> at rest p50", stats["sigint_to_rest_ms"]["p50"],
                    stats["stop_call_to_rest_ms"]["p50"], unit="ms"),
        ],
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=20)
    ap.add_argument("--signal", choices=("INT", "TERM", "HUP"), default="INT")
    cli = ap.parse_args()
    SIGNAL = signal.Signals[f"SIG{cli.signal}"]
    print(json.dumps(asyncio.run(main(cli.rounds)), indent=2))
