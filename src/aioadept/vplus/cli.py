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
    from aioadept.sim.server import publish_robot_states, robot_state_sample, world_state_sample
    from aioadept.vplus import Emulator, RealClock
    from aioadept.vplus.iodev import Network
    from aioadept.vplus.loader import load_files
    from aioadept.vplus.parse import norm
    from aioadept.vplus.robot import RobotDevice

    port_map = parse_port_map(args.map_port)
    ctl = options.make_controller()

    def console(task: int, text: str) -> None:
        print(f"[{task}] {text}", flush=True)

    module = load_files(args.vplus)
    clock = RealClock()
    wall0 = time.time() - clock.now
    emu = Emulator(module, robot=RobotDevice(ctl), clock=clock, console=console, cycle_s=args.vplus_cycle,
                   disk_dir=getattr(args, "disk", None))
    for p in emu.problems:
        print(f"aioadept sim: {p}", file=sys.stderr, flush=True)
    run_name = norm(args.run)
    if run_name not in module.programs:
        print(f"aioadept sim: --run {args.run}: no such program in {', '.join(args.vplus)}", file=sys.stderr,
              flush=True)
        return 2

    publisher = None
    state = "none"
    if options.state_endpoint is not None:
        from aioadept.bus.pubsub import Publisher

        publisher = Publisher(options.state_endpoint, bind=True, curve=options.state_curve)
        state = publisher.actual_endpoint

    listening = [False]

    def on_listen(vport: int, host: str, port: int) -> None:
        from aioadept.bus.zenoh import announce_ready

        listening[0] = True

        announce_ready()  # --transport zenoh: the node's liveliness token (no-op on ZeroMQ)
        print(f"READY host={host} port={port} vport={vport} state={state}", flush=True)

    emu.rt.devices = Network(args.host, port_map, on_listen, faults=options.faults)
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    # the emulator's clock is the controller's time: the stream samples the arm at that time
    io_cursor = [0]  # each signal change goes out once, in the sample after it
    world_cursor = [0]  # each world event too
    world_sample = None if ctl.world is None else (lambda: world_state_sample(ctl, clock.now, wall0, world_cursor))
    states = None if publisher is None else asyncio.ensure_future(publish_robot_states(
        publisher, lambda: robot_state_sample(ctl, clock.now, wall0, io_cursor), options.state_rate_hz,
        world_sample=world_sample))
    status = [0]
    watcher = asyncio.ensure_future(_watch(emu, args.run, listening, stop, status))
    try:
        emu.execute(0, args.run)
        await emu.serve(stop)
    finally:
        watcher.cancel()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
        for n in list(emu.rt.tasks):
            emu.rt.abort(n)
        if states is not None:
            states.cancel()
            await asyncio.gather(states, return_exceptions=True)
        if publisher is not None:
            publisher.close()
    return status[0]


async def _watch(emu: Any, run: str, listening: list[bool], stop: asyncio.Event, status: list[int]) -> None:
    """Never hang silently: when the --run program stops with an error before a socket is open, or no task is
    left to run, say why on stderr (one line) and stop the emulator; the exit status is 1 unless every task ended
    normally after the program was serving (a clean ``rs.halt``)."""
    rt = emu.rt
    while not stop.is_set():
        await asyncio.sleep(0.05)
        main = rt.tasks.get(0)
        failed = [T for T in rt.tasks.values() if T.state == "error"]
        if main is not None and main.state == "error" and not listening[0]:
            why = f"{run} stopped before it opened a socket: {_explain(main.error)}"
        elif not rt.active():
            if failed:
                why = f"V+ task {failed[0].num} stopped: {_explain(failed[0].error)}"
            elif not listening[0]:
                why = f"{run} ended before it opened a socket (no V+ task is running)"
            else:
                print("aioadept sim: every V+ task has ended", file=sys.stderr, flush=True)
                stop.set()
                return
        else:
            continue
        print(f"aioadept sim: {why}", file=sys.stderr, flush=True)
        status[0] = 1
        stop.set()
        return



def _explain(err: Any) -> str:
    """A task's error, and for an undefined program the likely cause: its module was not loaded. (V+ reports an
    undefined program only when the CALL executes, so a program the run never reaches is not an error: the
    shipped server calls rs.state only with the state stream on.)"""
    from aioadept.vplus import errors as E

    text = str(err)
    if getattr(err, "code", None) == E.UNDEFINED_PROGRAM:
        name = str(err.message).replace("*Undefined program*", "").strip()
        text += f": no loaded file defines {name} (load its module too)"
    return text
