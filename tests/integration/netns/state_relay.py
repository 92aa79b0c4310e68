"""The robot state relay on the MasterControlNode: ZeroMQ SUB on the robot net -> PUB on the vision net.

``python state_relay.py --sub tcp://10.231.1.2:PORT --pub tcp://10.231.2.1:0 [--topic robot.state]``

In the paper the camera looks at the real arm; in the simulated cell the virtual camera needs the sim's robot state
instead, and the sim lives on the robot net, which the vision net cannot reach. This process runs in the MCN (the only
host on both nets) and forwards the state messages at the application level, frames unchanged: one SUB connected to
the sim's state PUB, one PUB bound on MCN's vision-net address for the vision node to connect to. No IP packet
crosses between the nets.

Prints ``READY sub=... pub=<bound endpoint>`` once the first state message has arrived from upstream (so the robot
net leg is proven before anyone relies on it); exits 1 if none comes within ``--first-timeout`` s. On SIGINT/SIGTERM
prints ``RELAYED messages=N`` (also written to
``--stats FILE`` as JSON, which a supervisor can read after the exit without racing the pipe) and exits 0.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import time

import zmq


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sub", required=True, help="upstream state PUB to connect to (the sim's --state-endpoint)")
    p.add_argument("--pub", required=True, help="endpoint to bind for the vision node (port 0: any)")
    p.add_argument("--topic", default="robot.state")
    p.add_argument("--first-timeout", type=float, default=15.0)
    p.add_argument("--stats", help="write {\"relayed\": N} here on exit")
    args = p.parse_args(argv)

    stop = False

    def on_signal(_sig: int, _frame: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)

    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    pub = ctx.socket(zmq.PUB)
    relayed = 0
    try:
        for s in (sub, pub):
            s.setsockopt(zmq.LINGER, 0)
        sub.setsockopt(zmq.SUBSCRIBE, args.topic.encode())
        sub.connect(args.sub)
        endpoint = args.pub
        if endpoint.endswith(":0"):
            endpoint = endpoint[:-2] + ":*"
        pub.bind(endpoint)
        bound = pub.getsockopt(zmq.LAST_ENDPOINT).decode()
        poller = zmq.Poller()
        poller.register(sub, zmq.POLLIN)
        deadline = time.monotonic() + args.first_timeout
        while not stop:
            if not poller.poll(100):
                if relayed == 0 and time.monotonic() > deadline:
                    print(f"relay: no state message from {args.sub} within {args.first_timeout:g} s",
                          file=sys.stderr, flush=True)
                    return 1
                continue
            pub.send_multipart(sub.recv_multipart())
            relayed += 1
            if relayed == 1:
                print(f"READY sub={args.sub} pub={bound}", flush=True)
        print(f"RELAYED messages={relayed}", flush=True)
        return 0
    finally:
        if args.stats:
            with open(args.stats, "w") as fh:
                json.dump({"relayed": relayed}, fh)
        sub.close(0)
        pub.close(0)
        ctx.term()


if __name__ == "__main__":
    sys.exit(main())
