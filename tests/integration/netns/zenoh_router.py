"""The cell's Zenoh router on the MasterControlNode, listening on its address on each net (docs/topology.md).

``python zenoh_router.py --listen tcp/10.231.1.1:7447 --listen tcp/10.231.2.1:7447 [--cell topo]``

It replaces the ZeroMQ state relay of the two-network cell: the sim (robot net) and the vision node (vision net)
each connect to MCN's address on their own net, and the router forwards only what is subscribed, at the
application level, so the virtual camera follows the robot state and the MCN's focus app reaches the camera with no
IP packet crossing between the nets. Multicast scouting and gossip off, as every aioadept session. Declares itself
as node ``router`` of the cell, prints ``READY listen=A,B`` and runs until SIGINT/SIGTERM (exit 0).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--listen", action="append", required=True, help="tcp/HOST:PORT (repeatable)")
    p.add_argument("--cell", default="topo")
    args = p.parse_args(argv)
    from aioadept.bus import zenoh as zb

    done = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: done.set())
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    zb.configure(zb.ZenohOptions(mode="router", connect=(), listen=tuple(args.listen)))
    zb.declare_node(args.cell, "router")
    print(f"READY listen={','.join(args.listen)}", flush=True)
    while not done.wait(0.2):
        pass
    zb.close_session()
    return 0


if __name__ == "__main__":
    sys.exit(main())
