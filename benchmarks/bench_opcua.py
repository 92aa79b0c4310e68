"""``aioadept opcua``: from a robot.state sample to an OPC UA client's data change, against a plain bus subscriber of
the same stream in the same run; and what 20 subscribed clients cost the server.

An ``aioadept sim`` (state at ``--rate`` Hz, the arm kept moving between two joint targets so every sample changes)
and an ``aioadept opcua`` following it run as child processes on 127.0.0.1. This process holds:

- **baseline**: a plain ZeroMQ subscriber of robot.state; a sample's latency is its arrival (``time.time()``) minus
  the sample's ``wall_time_s``.
- **OPC UA**: an asyncua client subscribed (publishing interval ``--interval`` ms) to the six ActualPosition values;
  a data change's latency is its arrival minus its SourceTimestamp, which is the same ``wall_time_s``.

Goal: the OPC UA p95 within two publishing intervals (100 ms at 50 ms). The ``Stop`` method (the
server runs with ``--allow-commands``) during a motion, from the call to its result, against ``RobotClient.stop()``
direct, alternating, each from rest at A towards B; both are acked at rest, so both hold the sim's ramp (about 0.1 s
from the speed reached): goal, the issue's "acked within 100 ms" as what the OPC UA path adds, p95 against p95. The server's CPU (psutil: its
process's user + system time over a window, % of one core) with ``--clients`` clients each subscribed to the six
values at 100 ms, against the same window with none; goal: the clients cost <= 10 % of one core.

Prints one JSON object. Usage: ``python benchmarks/bench_opcua.py [--seconds 10] [--clients 20]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

from verdicts import verdict

ROBOTICS_NS = "http://opcfoundation.org/UA/Robotics/"
DI_NS = "http://opcfoundation.org/UA/DI/"
A = [20.0, -80.0, 170.0, 10.0, 60.0, -20.0]
B = [-20.0, -100.0, 190.0, -10.0, 80.0, 20.0]


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, int(q * len(s)))] if s else float("nan")


def summary_ms(xs: list[float]) -> dict:
    return {"n": len(xs), "p50": round(pct(xs, 0.5) * 1e3, 3), "p95": round(pct(xs, 0.95) * 1e3, 3),
            "max": round(max(xs) * 1e3, 3) if xs else None}


async def positions(client) -> list:
    """The six ActualPosition nodes, by their string node ids (the server's naming, docs/opcua.md)."""
    from asyncua import ua

    idx = await client.get_namespace_index("urn:aioadept:opcua:cell")
    rns = await client.get_namespace_index(ROBOTICS_NS)
    dns = await client.get_namespace_index(DI_NS)
    out = []
    for i in range(1, 7):
        axis = client.get_node(ua.NodeId(f"MotionDeviceSystem.Robot1.Axis{i}", idx))
        out.append(await axis.get_child([ua.QualifiedName("ParameterSet", dns),
                                         ua.QualifiedName("ActualPosition", rns)]))
    return out


class Latencies:
    def __init__(self) -> None:
        self.on = False
        self.values: list[float] = []

    def datachange_notification(self, node, val, data) -> None:
        if self.on:
            src = data.monitored_item.Value.SourceTimestamp
            if src is not None:
                self.values.append(time.time() - src.timestamp())


async def keep_moving(port: int, stop: asyncio.Event) -> None:
    from aioadept.client import RobotClient
    from aioadept.commands import MoveJoints, SetSpeed

    async with RobotClient("127.0.0.1", port) as robot:
        await robot.cmdexec(SetSpeed(20))
        while not stop.is_set():
            for target in (A, B):
                await robot.cmdexec(MoveJoints(target))


def cpu_pct(proc, seconds: float) -> float:
    """``proc``'s CPU over ``seconds`` (blocking sleep: call it in a thread), % of one core."""
    t0, c0 = time.monotonic(), sum(proc.cpu_times()[:2])
    time.sleep(seconds)
    return (sum(proc.cpu_times()[:2]) - c0) / (time.monotonic() - t0) * 100


async def stop_trials(url: str, port: int, users: Path, n: int) -> tuple[list[float], list[float]]:
    """``n`` stops of a running motion each way, alternating: the OPC UA ``Stop`` method (call to result, through
    ``aioadept opcua``'s RobotClient) and ``RobotClient.stop()`` direct. Both are acked at rest, so both include the
    deceleration ramp."""
    from asyncua import Client, ua

    from aioadept.client import RobotClient
    from aioadept.commands import MoveJoints, SetSpeed
    from aioadept.errors import CommandAborted

    client = Client(url, timeout=60)
    client.set_user("bench")
    client.set_password("bench")
    via_opc: list[float] = []
    direct: list[float] = []
    async with client, RobotClient("127.0.0.1", port) as robot, RobotClient("127.0.0.1", port) as other:
        vidx = await client.get_namespace_index("urn:aioadept:opcua:commands")
        idx = await client.get_namespace_index("urn:aioadept:opcua:cell")
        device = client.get_node(ua.NodeId("MotionDeviceSystem.Robot1", idx))
        method = await device.get_child([ua.QualifiedName("Stop", vidx)])
        await robot.cmdexec(SetSpeed(20))
        for i in range(2 * n):
            # Every trial the same: from rest at A towards B, stopped 0.1 s after it started moving (the ramp to rest,
            # part of both figures, depends on the speed reached).
            await robot.cmdexec(MoveJoints(A))
            motion = asyncio.create_task(robot.cmdexec(MoveJoints(B)))
            while not (await other.status()).moving:
                await asyncio.sleep(0.01)
            await asyncio.sleep(0.1)  # under way, at speed
            t0 = time.perf_counter()
            if i % 2 == 0:
                await device.call_method(method)
                via_opc.append(time.perf_counter() - t0)
            else:
                await other.stop()
                direct.append(time.perf_counter() - t0)
            try:
                await motion
            except CommandAborted:
                pass
    return via_opc, direct


async def bench(args: argparse.Namespace) -> dict:
    import psutil
    from asyncua import Client

    from aioadept.apps.cell import free_port
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.pubsub import Subscriber
    from aioadept.testing.nodes import running_node

    logs = Path(tempfile.mkdtemp(prefix="bench-opcua-"))
    url = f"opc.tcp://127.0.0.1:{free_port()}"
    async with running_node("sim", "--port", "0", "--state-rate", str(args.rate), "--state-endpoint",
                            "tcp://127.0.0.1:0", log_path=logs / "sim.log") as sim:
        users = logs / "users"
        users.write_text("bench:bench\n")
        users.chmod(0o600)
        async with running_node("opcua", "--robot", f"127.0.0.1:{sim.ready['port']}", "--state-endpoint",
                                sim.ready["state"], "--endpoint", url, "--allow-commands", "--users", str(users),
                                log_path=logs / "opcua.log", ready_timeout_s=120) as server:
            assert server.proc is not None
            server_proc = psutil.Process(server.proc.pid)
            stop = asyncio.Event()
            mover = asyncio.create_task(keep_moving(int(sim.ready["port"]), stop))
            bus: list[float] = []
            opc = Latencies()
            async with Subscriber(sim.ready["state"], topics=(ROBOT_STATE_TOPIC,)) as sub, \
                    Client(url, timeout=60) as client:
                nodes = [n.nodeid for n in await positions(client)]
                subscription = await client.create_subscription(args.interval, opc)
                await subscription.subscribe_data_change([client.get_node(n) for n in nodes])

                async def follow() -> None:
                    async for _t, payload in sub:
                        if opc.on:
                            bus.append(time.time() - RobotState.from_bytes(payload).wall_time_s)

                follower = asyncio.create_task(follow())
                await asyncio.sleep(1.0)  # the arm under way, both subscribers receiving
                opc.on = True
                await asyncio.sleep(args.seconds)
                opc.on = False
                follower.cancel()
                await asyncio.gather(follower, return_exceptions=True)
                cpu_idle = await asyncio.to_thread(cpu_pct, server_proc, args.cpu_seconds)
                clients = []
                try:
                    for _ in range(args.clients):
                        c = Client(url, timeout=60)
                        await c.connect()
                        clients.append(c)
                        s = await c.create_subscription(100, Latencies())
                        await s.subscribe_data_change([c.get_node(n) for n in nodes])
                    # The sessions' set-up (channels, subscriptions, first values) is over: the window holds what
                    # subscribed clients cost while they are served.
                    await asyncio.sleep(args.settle)
                    cpu_loaded = await asyncio.to_thread(cpu_pct, server_proc, args.cpu_seconds)
                finally:
                    for c in clients:
                        await c.disconnect()
            stop.set()
            await asyncio.wait_for(mover, 30)
            stops_opc, stops_direct = await stop_trials(url, int(sim.ready["port"]), users, args.stops)
    opc_p95, bus_p95 = pct(opc.values, 0.95), pct(bus, 0.95)
    cost = cpu_loaded - cpu_idle
    return {
        "benchmark": "bench_opcua",
        "python": platform.python_version(), "machine": platform.machine(), "cpus": os.cpu_count(),
        "state_rate_hz": args.rate, "publishing_interval_ms": args.interval, "seconds": args.seconds,
        "bus_subscriber": summary_ms(bus), "opcua_data_change": summary_ms(opc.values),
        "server_cpu_pct_one_core": {"with_1_client": round(cpu_idle, 2),
                                    f"with_{args.clients + 1}_clients": round(cpu_loaded, 2)},
        "stop_via_opcua": summary_ms(stops_opc), "stop_direct": summary_ms(stops_direct),
        "stop_via_opcua_ms_each": [round(x * 1e3, 1) for x in stops_opc],
        "stop_direct_ms_each": [round(x * 1e3, 1) for x in stops_direct],
        "verdicts": [
            verdict("Stop method during a motion, call to ack at rest (vs RobotClient.stop() direct), p95",
                    pct(stops_opc, 0.95) * 1e3, pct(stops_direct, 0.95) * 1e3, unit="ms",
                    goal="figure - baseline <= 100 ms (both wait for the ramp to rest)",
                    passed=pct(stops_opc, 0.95) - pct(stops_direct, 0.95) <= 0.100),
            verdict(f"robot.state sample -> OPC UA data change p95 (vs a bus subscriber's p95), publishing "
                    f"interval {args.interval:g} ms", opc_p95 * 1e3, bus_p95 * 1e3, unit="ms",
                    goal=f"figure <= {2 * args.interval:g} ms", passed=opc_p95 * 1e3 <= 2 * args.interval),
            verdict(f"opcua server CPU with {args.clients} more clients subscribed at 100 ms (vs one client)",
                    cpu_loaded, cpu_idle, unit="% core", goal="figure - baseline <= 10",
                    passed=cost <= 10.0),
        ],
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=10.0, help="latency window")
    p.add_argument("--cpu-seconds", type=float, default=5.0, dest="cpu_seconds", help="each CPU window")
    p.add_argument("--clients", type=int, default=20, help="clients added for the CPU figure")
    p.add_argument("--settle", type=float, default=2.0, help="seconds after the last client subscribed before the "
                                                             "CPU window")
    p.add_argument("--rate", type=int, default=50, help="the sim's state rate, Hz")
    p.add_argument("--interval", type=float, default=50.0, help="the OPC UA publishing interval, ms")
    p.add_argument("--stops", type=int, default=10, help="stops of a running motion each way")
    args = p.parse_args()
    print(json.dumps(asyncio.run(bench(args)), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
