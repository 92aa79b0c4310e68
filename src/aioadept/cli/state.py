"""``aioadept state``: relay a V+ controller's state stream (vplus/rsstate.V2) onto the robot.state topic.

Connects to the server's state port (``rs.stport``, 1236), turns each line into the RobotState message that
``aioadept sim`` publishes, and publishes it on ``--state-endpoint``, so the live view, the recording and the vision
node's virtual camera see a real arm as they see the sim's. Over ZeroMQ (the default) or Zenoh (``--transport
zenoh``: the cell's key aioadept/CELL/sim/state, where the sim would publish). ``--config CELL.toml`` takes the
controller's host and the state endpoint from ``[robot]`` and the transport from ``[bus]``, as the demo's
application uses them. Reconnects with backoff while the controller is away. Prints ``READY state=ENDPOINT
source=HOST:PORT`` once it publishes; runs until SIGINT/SIGTERM.
"""

from __future__ import annotations

import argparse
import asyncio
import signal
import sys

from aioadept import defaults
from aioadept.cli.options import (
    ArgumentParser,
    DefaultsHelpFormatter,
    add_insecure_option,
    add_node_transport_options,
    check_listeners,
    description,
    zenoh_listener,
    zmq_listener,
)

STREAMS = {"state_endpoint": (defaults.STATE_ENDPOINT, "sim", "state")}
"""The relay's one stream: (its ZeroMQ default, owner, topic); on Zenoh the key the sim's state has."""


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="aioadept state", description=description(__doc__), formatter_class=DefaultsHelpFormatter)
    p.add_argument("--config", metavar="FILE",
                   help="cell file (examples/cell.toml): [robot] host (with port 1236) and state_endpoint, and [bus] "
                        "(the transport; on zenoh the cell, the router to connect to and the cell's state key, as "
                        "the demo's application uses them); the whole file is checked as demo checks it; options "
                        "given here override it")
    p.add_argument("--robot", default=f"{defaults.ROBOT_HOST}:{defaults.STATE_STREAM_PORT}", metavar="HOST[:PORT]",
                   help="the V+ server's state port (rs.stport in rsconfig.V2)")
    p.add_argument("--state-endpoint", default=defaults.STATE_ENDPOINT, dest="state_endpoint",
                   help="endpoint to publish robot.state on (as aioadept sim --state-endpoint): a ZeroMQ PUB, or "
                        "zenoh:KEY")
    p.add_argument("--state-curve-secret", metavar="FILE", dest="state_curve_secret",
                   help="CURVE: this node's secret certificate; encrypts the stream (docs/security.md)")
    p.add_argument("--state-curve-allow", action="append", default=[], metavar="FILE", dest="state_curve_allow",
                   help="CURVE: public certificate of a subscriber allowed in (repeatable)")
    p.add_argument("--log-level", default="WARNING", dest="log_level", help="logging level on stderr")
    add_node_transport_options(p)
    add_insecure_option(p)
    return p


def parse_args(parser: argparse.ArgumentParser, argv: list[str] | None) -> argparse.Namespace:
    """Defaults < the cell file's ``[robot]`` and ``[bus]`` tables (``--config``) < the command line. ValueError
    (one line naming the file and the key) for a bad file."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    if args.config:
        from aioadept.cell.config import CellConfig
        from aioadept.cli.options import apply_cell_bus

        cell = CellConfig.from_toml(args.config)
        robot = f"{cell.robot.host}:{defaults.STATE_STREAM_PORT}"
        parser.set_defaults(robot=robot, state_endpoint=cell.robot.state_endpoint)
        args = parser.parse_args(argv)
        given = {k for k in ("transport", "cell", "zenoh_connect", "zenoh_listen", "zenoh_config") if getattr(args, k)}
        if args.state_endpoint != cell.robot.state_endpoint:
            given.add("state_endpoint")
        apply_cell_bus(vars(args), cell.bus, given, {k: v[1:] for k, v in STREAMS.items()}, args.config)
    return args


async def run(host: str, port: int, endpoint: str, curve) -> int:
    from aioadept.bus.pubsub import Publisher
    from aioadept.client.statestream import StateRelay

    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    publisher = Publisher(endpoint, bind=True, curve=curve)
    relay = StateRelay(host, port, publisher)
    task = asyncio.create_task(relay.run(), name="state-relay")
    try:
        from aioadept.bus.zenoh import announce_ready

        announce_ready()  # --transport zenoh: the node's liveliness token (no-op on ZeroMQ)
        print(f"READY state={publisher.actual_endpoint} source={host}:{port}", flush=True)
        await stop.wait()
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        publisher.close()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
    return 0


def main(argv: list[str] | None = None) -> int:
    from aioadept.cli.options import apply_node_transport, parse_robot_address
    from aioadept.cell.schema import report
    from aioadept.cli.sim import _state_curve

    parser = build_parser()
    try:
        args = parse_args(parser, argv)
    except (ValueError, OSError) as exc:   # the cell file: one line naming the file and the key
        return report("aioadept state", exc)
    from aioadept.cli.options import setup_logging

    setup_logging(args.log_level)
    try:
        host, port = parse_robot_address(args.robot, defaults.STATE_STREAM_PORT)
        apply_node_transport(vars(args), "state", STREAMS)
        curve = _state_curve(args)
        check_listeners("aioadept state", [
            *zmq_listener("--state-endpoint", args.state_endpoint, True, curve is not None, "read the robot's state"),
            *zenoh_listener(args, "read and publish the cell's streams")], args.insecure)
    except (ValueError, OSError) as exc:   # one line naming the option or the file, no usage block
        return report("aioadept state", exc)
    from aioadept.cli.options import run_node

    return run_node("aioadept state", run(host, port, args.state_endpoint, curve))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
