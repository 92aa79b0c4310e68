#!/usr/bin/env python3
"""Run the paper's two-network cell (Fig. 5) in network namespaces, and say what was done.

    sudo .venv/bin/python scripts/netns_cell.py [--time-scale 20] [--speed 25] [--delta-z 2] [--keep DIR] [--json]

Creates three namespaces (ROB: robot net, VIS: vision net, MCN: on both, no forwarding) joined by veth pairs, starts
``aioadept sim`` in ROB, the robot-state relay and then ``aioadept focus`` in MCN, ``aioadept vision`` in VIS;
probes that ROB and VIS cannot reach each other while both reach MCN; prints every command, the probe results and
the focus result; stops every process and deletes the namespaces, also on failure or Ctrl-C.
Exit code: 0 if the focus app completed with a peak and the nets were isolated, 1 otherwise, 2 if this machine
cannot create namespaces (needs root and iproute2). Details: docs/topology.md.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "integration" / "netns"))

from cell import run_cell  # noqa: E402
from topology import NetnsUnavailable, create, destroy  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--time-scale", type=float, default=20.0, help="sim motion speed-up (default 20)")
    p.add_argument("--speed", type=int, default=25, help="approach speed (default 25)")
    p.add_argument("--delta-z", type=float, default=2.0, help="tool z step, mm (default 2)")
    p.add_argument("--keep", type=Path, help="keep logs and the run folder here (default: a temporary folder)")
    p.add_argument("--json", action="store_true", help="print the whole report as JSON at the end")
    args = p.parse_args(argv)

    try:
        topo = create("aioadept-cell")
    except NetnsUnavailable as exc:
        print(f"cannot build the topology here: {exc}", file=sys.stderr)
        return 2
    try:
        print("topology:")
        for cmd in topo.commands:
            print(f"$ {cmd}")
        with tempfile.TemporaryDirectory(prefix="aioadept-netns-") as tmp:
            workdir = args.keep or Path(tmp)
            workdir.mkdir(parents=True, exist_ok=True)
            try:
                report = asyncio.run(run_cell(topo, workdir, time_scale=args.time_scale, speed=args.speed,
                                              delta_z_mm=args.delta_z, say=print))
            except Exception as exc:  # a node did not start, say; its output tail is in the message
                print(f"cell run failed: {type(exc).__name__}: {exc}", file=sys.stderr)
                return 1
    finally:
        problems = destroy(topo)
        print(f"namespaces {', '.join(topo.namespaces)} deleted" + (f" ({'; '.join(problems)})" if problems else ""))
    isolated = not any(r["reachable"] for r in report["reachability"]["across"])
    controls = all(r["reachable"] for r in report["reachability"]["controls"])
    bridged = all(r["reachable"] for r in report["reachability"]["bridged"])
    focus = report["focus"] or {}
    ok = report["focus_exit"] == 0 and "peak_index" in focus and isolated and controls and bridged
    print(f"MCN ip_forward={report['mcn_ip_forward']}; ROB<->VIS isolated: {isolated}; "
          f"MCN reaches both / both reach MCN: {controls}; "
          f"ROB reached VIS while MCN forwarded for a moment (probe check): {bridged}")
    if "peak_index" in focus:
        print(f"focus: peak at step {focus['peak_index']} ({focus['peak_offset_mm']:g} mm), "
              f"{focus['steps']} steps, sharpness {[round(s, 1) for s in focus['sharpness']]}")
    else:
        print(f"focus failed:\n{report['focus_log_tail']}")
    if args.json:
        print(json.dumps(report, indent=2, default=str))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
