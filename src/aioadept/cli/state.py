"""``aioadept state``: relay a V+ controller's state stream (vplus/rsstate.V2) onto the robot.state topic.

Connects to the server's state port (``rs.stport``, 1236), turns each line into the RobotState message that
``aioadept sim`` publishes, and publishes it on ``--state-endpoint``, so the live view, the recording and the vision
node's virtual camera see a real arm as they see the sim's. Reconnects with backoff while the controller is away.
Prints ``READY state=ENDPOINT source=HOST:PORT`` once the endpoint is bound; runs until SIGINT/SIGTERM.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
import sys

from aioadept import defaults
from aioadept.cli.options import DefaultsHelpFormatter, description


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="aioadept state", description=description(__doc__),
                                formatter_class=DefaultsHelpFormatter)
    p.add_argument("--robot", default=f"{defaults.ROBOT_HOST}:{defaults.STATE_STREAM_PORT}", metavar="HOST[:PORT]",
                   help="the V+ server's state port (rs.stport in rsconfig.V2)")
    p.add_argument("--state-endpoint", default=defaults.STATE_ENDPOINT, dest="state_endpoint",
                   help="ZeroMQ PUB endpoint to publish robot.state on (as aioadept sim --state-endpoint)")
    p.add_argument("--state-curve-secret", metavar="FILE", dest="state_curve_secret",
                   help="CURVE: this node's secret certificate; encrypts the stream (docs/security.md)")
    p.add_argument("--state-curve-allow", action="append", default=[], metavar="FILE", dest="state_curve_allow",
                   help="CURVE: public certificate of a subscriber allowed in (repeatable)")
    p.add_argument("--log-level", default="WARNING", dest="log_level", help="logging level on stderr")
    return p


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
    from aioadept.cli.options import parse_robot_address, report
    from aioadept.cli.sim import _state_curve

    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), stream=sys.stderr,
                        format="%(asctime)s %(name)s %(levelname)s %(message)s")
    try:
        host, port = parse_robot_address(args.robot, defaults.STATE_STREAM_PORT)
        curve = _state_curve(args)
    except (ValueError, OSError) as exc:   # one line naming the option or the file, no usage block
        return report("aioadept state", exc)
    try:
        return asyncio.run(run(host, port, args.state_endpoint, curve))
    except Exception as exc:  # BusError binding the endpoint, etc.
        from aioadept.errors import AdeptError

        if isinstance(exc, (OSError, AdeptError)):
            print(f"aioadept state: {exc}", file=sys.stderr)
            return 1
        raise


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
