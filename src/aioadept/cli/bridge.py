"""``aioadept bridge``: share one robot between several applications over Zenoh (docs/bridge.md).

Holds the one TCP connection to a RobotServer (the V+ AdeptServer, ``aioadept sim`` or the V+ emulator; its stop
port too) and serves the robot's commands as Zenoh queries on ``aioadept/<cell>/<name>/cmd`` to any number of
:class:`aioadept.bridge.BridgeClient` s; relays the controller's state stream (``--state-endpoint``, ZeroMQ) onto
``aioadept/<cell>/<name>/state``; declares the liveliness token ``aioadept/<cell>/<name>``. Multicast scouting is
off: it is the router (``--zenoh-listen``) or connects to one (``--zenoh-connect``). Prints
``READY cmd=KEY state=KEY|none robot=HOST:PORT`` once it serves; runs until SIGINT/SIGTERM. Refuses to start
(one line, exit 1) when another bridge already has the name on the Zenoh network.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
import sys

from aioadept import defaults
from aioadept.cli.options import (
    DefaultsHelpFormatter,
    add_insecure_option,
    add_zenoh_session_options,
    description,
    zenoh_session_options,
)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="aioadept bridge", description=description(__doc__),
                                formatter_class=DefaultsHelpFormatter)
    p.add_argument("--robot", default=f"{defaults.ROBOT_HOST}:{defaults.ROBOT_PORT}", metavar="HOST[:PORT]",
                   help="the RobotServer to hold the one connection to")
    p.add_argument("--stop-port", default="auto", dest="stop_port", metavar="PORT",
                   help="the server's stop port: 'auto' (PORT+1), a number, or 'none' (the original AdeptServer)")
    p.add_argument("--cell", default="demo", help="the cell's name in the key expressions")
    p.add_argument("--name", default="robot", help="this robot's name in the key expressions")
    add_zenoh_session_options(p)
    add_insecure_option(p)
    p.add_argument("--state-endpoint", default="none", dest="state_endpoint",
                   help="the controller's ZeroMQ state stream to relay (as aioadept sim --state-endpoint), or none")
    p.add_argument("--ack-timeout", type=float, default=60.0, dest="ack_timeout_s",
                   help="seconds to wait for a batch's acks (above the longest motion)")
    p.add_argument("--log-level", default="WARNING", dest="log_level", help="logging level on stderr")
    return p


def _options(args: argparse.Namespace):  # -> (host, port, stop_port, ZenohOptions)
    from aioadept.bridge.wire import bridge_key
    from aioadept.cli.options import check_listeners, parse_robot_address, zenoh_listener

    host, port = parse_robot_address(args.robot)
    stop = args.stop_port.strip().lower()
    if stop in ("auto", "none"):
        stop_port: int | str | None = None if stop == "none" else "auto"
    elif stop.isdigit() and 0 < int(stop) <= 0xFFFF:
        stop_port = int(stop)
    else:
        raise ValueError(f"--stop-port {args.stop_port!r}: expected auto, none or a port 1..65535")
    for opt, value in (("--cell", args.cell), ("--name", args.name)):
        try:
            bridge_key(value, value)
        except ValueError:
            raise ValueError(f"{opt} {value!r}: use 1-64 letters, digits, '_', '.', '-' (one key chunk)") from None
    opts = zenoh_session_options(args.zenoh_listen, args.zenoh_connect, args.zenoh_config)
    check_listeners("aioadept bridge", zenoh_listener(args, f"command the robot {args.cell}/{args.name}"),
                    args.insecure)
    state = args.state_endpoint.strip()
    if state.lower() != "none" and not state.startswith(("tcp://", "ipc://")):
        raise ValueError(f"--state-endpoint {state!r}: the controller's ZeroMQ state stream (tcp://HOST:PORT or "
                         "ipc://PATH), or none; a stream already on Zenoh needs no relay")
    if not (args.ack_timeout_s > 0 and args.ack_timeout_s < float("inf")):
        raise ValueError(f"--ack-timeout {args.ack_timeout_s!r}: a number of seconds > 0")
    return host, port, stop_port, opts


async def run(args: argparse.Namespace, host: str, port: int, stop_port, opts) -> int:
    from aioadept.bridge import Bridge
    from aioadept.bridge.wire import cmd_key, state_key
    from aioadept.bus import zenoh as zb
    from aioadept.client import RobotClient

    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    zb.configure(opts)
    robot = RobotClient(host, port, stop_port=stop_port, ack_timeout_s=args.ack_timeout_s)
    relay = None if args.state_endpoint.strip().lower() == "none" else args.state_endpoint
    try:
        async with Bridge(robot, cell=args.cell, name=args.name, state_endpoint=relay) as bridge:
            print(f"aioadept bridge: {who_may_command(args, opts)}", file=sys.stderr, flush=True)
            print(f"READY cmd={cmd_key(args.cell, args.name)} "
                  f"state={state_key(args.cell, args.name) if relay else 'none'} robot={host}:{port}", flush=True)
            waits = [asyncio.ensure_future(e.wait()) for e in (stop, bridge.taken)]
            try:
                await asyncio.wait(waits, return_when=asyncio.FIRST_COMPLETED)
            finally:
                for w in waits:
                    w.cancel()
            logging.getLogger("aioadept.bridge").info("bridge stats: %s", bridge.stats)
            if bridge.taken.is_set():
                print(f"aioadept bridge: {bridge.taken_reason}", file=sys.stderr, flush=True)
                return 1
    finally:
        zb.close_session()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
    return 0


def who_may_command(args: argparse.Namespace, opts) -> str:
    """One line: who may command the robot through this bridge (said at every start; docs/security.md)."""
    from aioadept.bridge.wire import bridge_key
    from aioadept.cli.options import is_loopback, listen_host, zenoh_authenticates

    robot = bridge_key(args.cell, args.name)
    where = (opts.listen or opts.connect)[0]
    if zenoh_authenticates(args.zenoh_config):
        return f"only processes with the credentials of {args.zenoh_config} that reach {where} may command {robot}"
    if opts.listen:
        who = ("any process on this machine" if is_loopback(listen_host(where) or "")
               else "ANY process on any machine")
        return f"{who} that reaches {where} may command {robot} (no Zenoh credentials configured)"
    return (f"any process that reaches the Zenoh router at {where} may command {robot} (no Zenoh credentials "
            "configured; who reaches the router is the router's setting)")


def limit_malloc_arenas(n: int = 2) -> None:
    """glibc gives each thread that allocates its own malloc arena; Zenoh's threads handing over a flood of queries
    then keep RSS growing round after round (bench_bridge: 54 -> 127 MB over 8 rounds of 5,000 refused queries, a
    plateau at ~90 MB with 2 arenas). Call before the Zenoh session opens; nothing on other C libraries."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.mallopt(-8, n)  # M_ARENA_MAX
    except (OSError, AttributeError):
        pass


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from aioadept.cli.options import setup_logging

    setup_logging(args.log_level)
    try:
        host, port, stop_port, opts = _options(args)
    except ValueError as exc:   # one line naming the option, no usage block
        print(f"aioadept bridge: {exc}", file=sys.stderr)
        return 2
    from aioadept.cli.options import run_node

    limit_malloc_arenas()
    return run_node("aioadept bridge", run(args, host, port, stop_port, opts))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
