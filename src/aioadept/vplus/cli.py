"""``aioadept sim --vplus FILE... --run PROGRAM``: the emulated controller running V+ code, in real time.

The files are loaded (problems are printed on stderr with file:line), PROGRAM runs in task 0, TYPE output and
task messages go to stdout as ``[task] text`` lines. Each ``FOPEN /LOCAL_PORT n`` binds ``--host`` on port n, or on
the port that ``--map-port n=m`` gives (m = 0: an ephemeral port), and prints
``READY host=H port=P vport=n state=none``, the line ``aioadept.testing.running_node`` waits for.
The robot is the Python sim's Controller (same kinematics, motion timing, --time-scale, --monitor-speed).
"""

from __future__ import annotations

import argparse
import asyncio
import signal
import sys

from aioadept.geometry import NULL, Pose


def parse_port_map(specs: list[str]) -> dict[int, int]:
    """``["1234=0", "5000=15000"]`` -> ``{1234: 0, 5000: 15000}``; raises ``ValueError``."""
    out: dict[int, int] = {}
    for spec in specs:
        try:
            v, h = spec.split("=", 1)
            vport, hport = int(v), int(h)
        except ValueError:
            raise ValueError(f"--map-port expects VPORT=HOSTPORT, got {spec!r}") from None
        if not (0 < vport < 65536 and 0 <= hport < 65536):
            raise ValueError(f"--map-port {spec!r}: port out of range")
        out[vport] = hport
    return out


async def run(args: argparse.Namespace) -> int:
    from aioadept.sim.controller import Controller
    from aioadept.vplus import Emulator, RealClock
    from aioadept.vplus.iodev import Network
    from aioadept.vplus.loader import load_files
    from aioadept.vplus.robot import RobotDevice

    port_map = parse_port_map(args.map_port)
    extra = {}
    if args.joints is not None:
        extra["joints_deg"] = args.joints
    ctl = Controller(tool=Pose(*args.tool) if args.tool else NULL, monitor_speed_pct=args.monitor_speed,
                     time_scale=args.time_scale, instant=args.instant, max_speed_pct=args.max_speed, **extra)

    def console(task: int, text: str) -> None:
        print(f"[{task}] {text}", flush=True)

    module = load_files(args.vplus)
    emu = Emulator(module, robot=RobotDevice(ctl), clock=RealClock(), console=console, cycle_s=args.vplus_cycle)
    for p in emu.problems:
        print(f"aioadept sim: {p}", file=sys.stderr, flush=True)

    def on_listen(vport: int, host: str, port: int) -> None:
        print(f"READY host={host} port={port} vport={vport} state=none", flush=True)

    emu.rt.devices = Network(args.host, port_map, on_listen)
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    try:
        emu.execute(0, args.run)
        await emu.serve(stop)
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
        for n in list(emu.rt.tasks):
            emu.rt.abort(n)
    return 0
