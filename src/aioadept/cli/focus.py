"""``aioadept focus``: run focus calibration against a robot server and a vision node given by address.

The same command works with the simulator or a real controller: nothing is started here, only connected to.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from aioadept.apps.cell import new_run_dir, run_focus_once
from aioadept.cell.config import CellConfig
from aioadept import defaults
from aioadept.cli.options import (
    ArgumentParser,
    add_cell_options,
    add_insecure_option,
    add_mode_option,
    add_robot_option,
    apply_overrides,
    configure_logging,
    description,
    parse_robot_address,
    with_default,
)
from aioadept.cell.schema import report
from aioadept.cli.report import run_once

log = logging.getLogger("aioadept.focus")


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="aioadept focus", description=description(__doc__))
    add_cell_options(p)
    add_mode_option(p)
    add_robot_option(p)
    p.add_argument("--request-endpoint", dest="request_endpoint",
                   help=with_default("PUB for vision requests: binds by default (as pyadept's MCN), '>tcp://...' "
                                     "connects to a node that binds it; the vision node's READY line prints the "
                                     "right form", defaults.REQUEST_ENDPOINT))
    p.add_argument("--response-endpoint", dest="response_endpoint",
                   help=with_default("SUB for vision responses: connects by default, '@tcp://...' binds",
                                     defaults.RESPONSE_ENDPOINT))
    add_insecure_option(p)
    return p


def main(argv: list[str] | None = None) -> int:
    """Exit codes: 0 found and saved; 1 the run failed (or a stop failed); 2 bad options or no run folder (nothing
    was moved); 4 found and printed, but files of the run folder were not written; 130 interrupted, robot stopped."""
    args = build_parser().parse_args(argv)
    configure_logging(args.verbose)
    try:
        cfg = CellConfig.from_toml(args.config) if args.config else CellConfig()
    except (OSError, ValueError) as exc:
        return report("aioadept focus", exc, verbose=args.verbose)
    cfg.robot.start_sim = False
    cfg.vision.start = False
    if args.robot:
        try:
            cfg.robot.host, cfg.robot.port = parse_robot_address(args.robot)
        except ValueError as exc:
            return report("aioadept focus", exc, verbose=args.verbose)
    # These options are the MCN's side of each link (as the node's READY line prints them); the cell file keeps
    # the node's side.
    from aioadept.bus.endpoints import opposite
    from aioadept.errors import BusError

    from aioadept.cli.options import check_listeners, zmq_listener

    try:
        check_listeners("aioadept focus", [
            *zmq_listener("--request-endpoint", args.request_endpoint, True, False, "read the vision requests"),
            *zmq_listener("--response-endpoint", args.response_endpoint, False, False,
                          "forge the sharpness answers that steer the tool")], args.insecure)
    except ValueError as exc:
        return report("aioadept focus", exc, verbose=args.verbose)
    try:
        if args.request_endpoint:
            cfg.vision.request_endpoint = opposite(args.request_endpoint)
        if args.response_endpoint:
            cfg.vision.response_endpoint = opposite(args.response_endpoint)
    except BusError as exc:
        print(f"aioadept focus: {exc}", file=sys.stderr)
        return 2
    try:
        cfg = apply_overrides(cfg, args)
    except ValueError as exc:
        return report("aioadept focus", exc, verbose=args.verbose)
    from aioadept.record.hook import refuse_view_without_rerun

    if refuse_view_without_rerun(args, "aioadept focus"):
        return 2
    try:
        run_dir = new_run_dir(cfg)
    except OSError as exc:  # before any connection: the robot is not moved for a run that could not be kept
        print(f"aioadept focus: cannot create a run folder in {cfg.run.out_dir!r}: {exc}; nothing was started",
              file=sys.stderr)
        return 2
    from aioadept.record.hook import run_with_viewer

    return run_with_viewer(args, "aioadept focus", cfg, run_dir / "viewer.log", lambda: _run(cfg, run_dir))


def _run(cfg: CellConfig, run_dir: Path) -> int:
    from aioadept.apps.cell import resolve_ports
    from aioadept.cell.bus import zenoh_session
    from aioadept.errors import BusError

    cfg = resolve_ports(cfg)  # [bus] transport = "zenoh": the cell's keys, and this process joins its router
    try:
        with zenoh_session(cfg):
            return run_once(lambda intr: run_focus_once(cfg, run_dir, interrupter=intr), run_dir,
                            analyze=cfg.run.analyze, prog="aioadept focus")
    except BusError as exc:
        print(f"aioadept focus: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
