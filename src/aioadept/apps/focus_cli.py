"""``aioadept focus``: run focus calibration against a robot server and a vision node given by address.

The same command works with the simulator or a real controller: nothing is started here, only connected to.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import sys

from aioadept.apps.cell import CellConfig, new_run_dir, run_focus_once
from aioadept.apps.cli_common import add_cell_options, apply_overrides, configure_logging, print_result

log = logging.getLogger("aioadept.focus")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="aioadept focus", description=__doc__.split("\n\n")[0])
    add_cell_options(p)
    p.add_argument("--robot", help="robot server HOST:PORT (default 127.0.0.1:1234)")
    p.add_argument("--request-endpoint", dest="request_endpoint", help="vision requests (default tcp://127.0.0.1:5555)")
    p.add_argument("--response-endpoint", dest="response_endpoint",
                   help="vision responses (default tcp://127.0.0.1:5556)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    configure_logging(args.verbose)
    cfg = CellConfig.from_toml(args.config) if args.config else CellConfig()
    cfg.robot.start_sim = False
    cfg.vision.start = False
    if args.robot:
        host, _, port = args.robot.rpartition(":")
        cfg.robot.host, cfg.robot.port = host or "127.0.0.1", int(port)
    if args.request_endpoint:
        cfg.vision.request_endpoint = args.request_endpoint
    if args.response_endpoint:
        cfg.vision.response_endpoint = args.response_endpoint
    cfg = apply_overrides(cfg, args)
    run_dir = new_run_dir(cfg)
    try:
        outcome = asyncio.run(run_focus_once(cfg, run_dir))
    except KeyboardInterrupt:
        return 130
    except Exception as exc:
        log.error("focus failed: %s: %s (log in %s)", type(exc).__name__, exc, run_dir)
        return 1
    assert outcome.result is not None
    print_result(outcome.result, run_dir)
    if cfg.run.analyze:
        from aioadept.analysis import analyze_runs

        analyze_runs([run_dir], run_dir)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
