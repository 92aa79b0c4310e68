"""``aioadept demo``: the whole simulated cell doing focus calibration, as separate processes on loopback.

It starts the simulated controller (``aioadept sim``) and the vision node with its virtual camera
(``aioadept vision``), runs the focus application in this process (the MasterControlNode), prints the found pose and
the sharpness curve, and writes a run folder: the timing log, the plots and a summary. Every node is stopped at the
end, also when a node fails. Ctrl-C stops the robot first, then the nodes; a second Ctrl-C kills them and exits at
once (:mod:`aioadept.apps.interrupt`).
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from aioadept.apps.cell import new_run_dir
from aioadept.cell.config import CellConfig
from aioadept.apps.demo import run_demo
from aioadept.cli.options import (
    ArgumentParser,
    add_cell_options,
    add_mode_option,
    apply_overrides,
    check_option,
    configure_logging,
    description,
    option_help,
)
from aioadept.cell.schema import report
from aioadept.cli.report import run_once

log = logging.getLogger("aioadept.demo")


def build_parser() -> argparse.ArgumentParser:
    from aioadept.cell.config import RobotSection
    from aioadept.vision.options import VisionOptions

    p = ArgumentParser(prog="aioadept demo", description=description(__doc__))
    add_cell_options(p)
    add_mode_option(p)
    p.add_argument("--time-scale", type=float, dest="time_scale",
                   help=option_help("run the simulated motion this many times faster than real time", RobotSection,
                                    "time_scale"))
    p.add_argument("--fast", action="store_true", help="same as --time-scale 10")
    p.add_argument("--focus-offset-mm", type=float, dest="focus_offset_mm",
                   help=option_help("virtual camera: focal plane distance beyond the approach pose along tool z",
                                    VisionOptions, "focus_offset_mm"))
    return p


def demo_config(args: argparse.Namespace) -> CellConfig:
    cfg = CellConfig.from_toml(args.config) if args.config else CellConfig()
    return with_demo_options(cfg, args, from_file=bool(args.config))


def with_demo_options(cfg: CellConfig, args: argparse.Namespace, *, from_file: bool) -> CellConfig:
    """``cfg`` with the demo's command-line options applied (ValueError naming the option)."""
    if not from_file:
        # Free ports, so the demo runs beside anything else on this machine.
        cfg.robot.port = 0
        cfg.robot.state_endpoint = "tcp://127.0.0.1:0"
        cfg.vision.request_endpoint = "tcp://127.0.0.1:0"
        cfg.vision.response_endpoint = "tcp://127.0.0.1:0"
    # Without a file the demo starts the whole cell; a file says itself which nodes run here (start_sim = false:
    # connect to the server at robot.host:port, e.g. a real controller, and fail if nothing answers there).
    if not from_file and args.transport == "zenoh":
        cfg.bus.zenoh_router = "tcp/127.0.0.1:0"  # a free port for this demo's router, as above
    if args.fast:
        cfg.robot.time_scale = 10.0
    if args.time_scale is not None:
        check_option("--time-scale", type(cfg.robot), "time_scale", args.time_scale)
        cfg.robot.time_scale = args.time_scale
    if args.focus_offset_mm is not None:
        check_option("--focus-offset-mm", type(cfg.vision), "focus_offset_mm", args.focus_offset_mm)
        cfg.vision.focus_offset_mm = args.focus_offset_mm
    return apply_overrides(cfg, args)


def main(argv: list[str] | None = None) -> int:
    """Exit codes as ``aioadept focus``: 0, 1 failed (or a stop failed), 2 bad options / no run folder, 4 result
    printed but not fully saved, 130 interrupted with the robot stopped (and every node stopped)."""
    args = build_parser().parse_args(argv)
    configure_logging(args.verbose)
    if args.config:
        from aioadept.cell.multi import is_multi
        from aioadept.cell.schema import load_toml

        try:
            data = load_toml(args.config)
        except ValueError as exc:
            return report("aioadept demo", exc, verbose=args.verbose)
        if is_multi(data):  # [[robots]] and [[cameras]]: every robot calibrates its camera at once
            from aioadept.cli.multi import main_multi

            return main_multi(args, data, with_demo_options)
    try:
        cfg = demo_config(args)
    except (OSError, ValueError) as exc:
        return report("aioadept demo", exc, verbose=args.verbose)
    from aioadept.record.hook import refuse_view_without_rerun

    if refuse_view_without_rerun(args, "aioadept demo"):
        return 2
    try:
        run_dir = new_run_dir(cfg)
    except OSError as exc:
        print(f"aioadept demo: cannot create a run folder in {cfg.run.out_dir!r}: {exc}; nothing was started",
              file=sys.stderr)
        return 2
    log.info("run folder %s", run_dir)
    from aioadept.record.hook import keep_frames, run_with_viewer

    keep_frames(cfg, args, run_dir / "frames")  # the frames the node served, for run.rrd and the view
    return run_with_viewer(args, "aioadept demo", cfg, run_dir / "logs" / "viewer.log", lambda: _run(cfg, run_dir))


def _run(cfg: CellConfig, run_dir: Path) -> int:
    code = run_once(lambda intr: run_demo(cfg, run_dir, interrupter=intr), run_dir, analyze=cfg.run.analyze,
                    prog="aioadept demo")
    if code == 0 and cfg.run.analyze:
        log.info("plots and summary.json written to %s", run_dir)
        _print_cycle(run_dir)
    return code


def _print_cycle(run_dir: Path) -> None:
    """The cycle split motion / vision and the vision floor, as summary.json's ``cycle`` holds them."""
    import json

    from aioadept.analysis.cycle import cycle_line

    try:
        line = cycle_line(json.loads((run_dir / "summary.json").read_text(encoding="utf-8")).get("cycle") or {})
    except (OSError, ValueError) as exc:
        log.warning("summary.json unreadable: %s", exc)
        return
    if line:
        print(line)
