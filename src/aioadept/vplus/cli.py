"""``aioadept sim --vplus FILE... --run PROGRAM``: the emulated controller running V+ code, in real time.

The files are loaded (problems are printed on stderr with file:line), PROGRAM runs in task 0, TYPE output and
task messages go to stdout as ``[task] text`` lines. Each ``FOPEN /LOCAL_PORT n`` binds ``--host`` on port n, or on
the port that ``--map-port n=m`` gives (m = 0: an ephemeral port), and prints
``READY host=H port=P vport=n state=none``, the line ``aioadept.testing.running_node`` waits for.
The robot is the Python sim's Controller (same kinematics, motion timing, --time-scale, --monitor-speed); the
ZeroMQ state stream (``--state-endpoint``, ``--state-rate-hz``, CURVE) and ``--fault`` work as with the Python
backend (the READY line names the stream's endpoint).
"""

from __future__ import annotations

import argparse
import asyncio
import signal
import sys
import time
from typing import Any


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


async def run(args: argparse.Namespace, options: Any) -> int:
    """Serve until SIGINT/SIGTERM. ``options`` (:class:`aioadept.sim.server.SimOptions`, from the same command
    line: ``aioadept.cli.sim.options_from_args``) gives the robot, the state stream and the faults exactly as for
    the Python backend."""
    from aioadept.sim.server import publish_robot_states, robot_state_sample
    from aioadept.vplus import Emulator, RealClock
    from aioadept.vplus.iodev import Network
    from aioadept.vplus.loader import load_files
    from aioadept.vplus.robot import RobotDevice

    port_map = parse_port_map(args.map_port)
    ctl = options.make_controller()

    def console(task: int, text: str) -> None:
        print(f"[{task}] {text}", flush=True)

    module = load_files(args.vplus)
    clock = RealClock()
    wall0 = time.time() - clock.now
    emu = Emulator(module, robot=RobotDevice(ctl), clock=clock, console=console, cycle_s=args.vplus_cycle)
    for p in emu.problems:
        print(f"aioadept sim: {p}", file=sys.stderr, flush=True)

    publisher = None
    state = "none"
    if options.state_endpoint is not None:
        from aioadept.bus.pubsub import Publisher

        publisher = Publisher(options.state_endpoint, bind=True, curve=options.state_curve)
        state = publisher.actual_endpoint

    def on_listen(vport: int, host: str, port: int) -> None:
        from aioadept.bus.zenoh import announce_ready

        announce_ready()  # --transport zenoh: the node's liveliness token (no-op on ZeroMQ)
        print(f"READY host={host} port={port} vport={vport} state={state}", flush=True)

    emu.rt.devices = Network(args.host, port_map, on_listen, faults=options.faults)
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    # the emulator's clock is the controller's time: the stream samples the arm at that time
    io_cursor = [0]  # each signal change goes out once, in the sample after it
    states = None if publisher is None else asyncio.ensure_future(publish_robot_states(
        publisher, lambda: robot_state_sample(ctl, clock.now, wall0, io_cursor), options.state_rate_hz))
    try:
        emu.execute(0, args.run)
        await emu.serve(stop)
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
        for n in list(emu.rt.tasks):
            emu.rt.abort(n)
        if states is not None:
            states.cancel()
            await asyncio.gather(states, return_exceptions=True)
        if publisher is not None:
            publisher.close()
    return 0
