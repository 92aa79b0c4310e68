"""``aioadept calibrate``: estimate the fixed camera's pose in the robot base frame from views of an ArUco marker on
the tool, and print (or write into a cell file) the ``[calibration]`` table the part locator uses.

It connects to a robot server (the sim or a real controller) and a vision node serving the part locator
(``aioadept vision --graph locate``). With ``--config CELL`` it starts what the cell file says this machine starts,
as ``aioadept demo`` does: the sim (``start_sim``, unless ``--robot`` is given) and the vision node (``start``,
unless ``--request-endpoint``/``--response-endpoint`` are), which must then be the world camera's part locator with
a ``[world.tool_marker]`` (its id and side are the defaults of ``--marker`` and ``--marker-mm``); the nodes' logs go
to ``<out_dir>/<stamp>-calibrate/logs``. The robot moves ``move_to`` + ``break`` through ``--views``
poses around ``--centre`` (tool pointing down), and the node is asked for the marker's corners at each. Every pose
is checked before the first motion (none below the table + 100 mm); after any error nothing more is moved, and
Ctrl-C (SIGTERM, SIGHUP) stops the arm where it is, as in ``aioadept focus``.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from aioadept import defaults
from aioadept.cli.options import (
    ArgumentParser,
    add_robot_option,
    add_verbose,
    description,
    parse_robot_address,
    setup_logging,
    with_default,
)
from aioadept.cell.schema import report
from aioadept.cell.schema import Range

log = logging.getLogger("aioadept.calibrate")

PROG = "aioadept calibrate"
RANGES = {"views": Range(3, 200, integer=True), "marker": Range(0, 999, integer=True),
          "marker_mm": Range(1.0, 500.0, unit="mm"), "speed": Range(1, 100, integer=True),
          "spread_mm": Range(0.0, 500.0, unit="mm"), "tilt_deg": Range(0.0, 45.0, unit="deg"),
          "vision_timeout": Range(0.0, 600.0, lo_open=True, unit="s")}


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog=PROG, description=description(__doc__))
    p.add_argument("--config", type=Path, metavar="FILE",
                   help="cell file: robot address, vision endpoints, [bus] (on Zenoh: the cell's keys and router), "
                        "the nominal [calibration] (intrinsics, table); defaults without it")
    add_robot_option(p)
    p.add_argument("--request-endpoint", help=with_default("PUB for locate requests (the node's READY line prints "
                                                           "the form to use)", defaults.REQUEST_ENDPOINT))
    p.add_argument("--response-endpoint", help=with_default("SUB for the answers", defaults.RESPONSE_ENDPOINT))
    p.add_argument("--centre", metavar="X,Y,Z", help="centre of the tool poses in the base frame, mm (default: below "
                                                     "the nominal camera, 300 mm above the table)")
    p.add_argument("--views", type=int, default=12, help=f"poses to visit ({RANGES['views'].text}; default 12)")
    p.add_argument("--spread-mm", type=float, default=60.0, help="position spread around the centre (default 60)")
    p.add_argument("--tilt-deg", type=float, default=20.0, help="tool tilt spread (default 20)")
    p.add_argument("--seed", type=int, default=0, help="pose generator seed (default 0)")
    p.add_argument("--marker", type=int, help="ArUco id of the marker on the tool (default: the cell's "
                                               "[world.tool_marker], else 0)")
    p.add_argument("--marker-mm", type=float, help="its side, black border included (default: the cell's "
                                                   "[world.tool_marker], else 40)")
    p.add_argument("--speed", type=int, default=20, help="motion speed, %% (default 20)")
    p.add_argument("--vision-timeout", type=float, default=5.0, help="seconds per locate request (default 5)")
    p.add_argument("--write", type=Path, metavar="FILE",
                   help="put the [calibration] table into this cell file (other tables are kept); without it the "
                        "table is printed only")
    add_verbose(p)
    return p


def _centre(text: str) -> tuple[float, float, float]:
    try:
        x, y, z = (float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--centre {text!r}: expected X,Y,Z in mm, e.g. 450,0,300") from None
    return x, y, z


def main(argv: list[str] | None = None) -> int:
    """Exit codes: 0 calibrated (printed, and written with --write); 1 the run failed (the robot is left where it
    is); 2 bad options or configuration (nothing was moved); 130 interrupted."""
    args = build_parser().parse_args(argv)
    # stdout carries the TOML table only (pipe it into a file); log lines go to stderr
    setup_logging(logging.DEBUG if args.verbose else logging.INFO, fmt="%(levelname)s %(name)s: %(message)s")
    from aioadept.apps.calibrate import calibration_poses, check_poses
    from aioadept.errors import CalibrationError
    from aioadept.cell.config import CellConfig
    from aioadept.cell.bus import with_transport, zenoh_session
    from aioadept.geometry import Pose
    from aioadept.vision.calibration import CameraCalibration

    try:
        # [bus] transport = "zenoh": the vision node's requests on the cell's keys, through the cell's router
        cfg = with_transport(CellConfig.from_toml(args.config) if args.config else CellConfig())
        start_sim, start_vision = _starts(args, cfg)
        tool = cfg.world.tool_marker if cfg.world is not None else None
        args.marker = args.marker if args.marker is not None else tool.marker if tool else 0
        args.marker_mm = args.marker_mm if args.marker_mm is not None else tool.marker_mm if tool else 40.0
        for key, rng in RANGES.items():
            rng.check("--" + key.replace("_", "-"), getattr(args, key), sep=" ")
        nominal = cfg.calibration if cfg.calibration is not None else CameraCalibration()
        host, port = parse_robot_address(args.robot) if args.robot else (cfg.robot.host, cfg.robot.port)
        if args.centre:
            cx, cy, cz = _centre(args.centre)
        else:
            cx, cy, cz = nominal.x_mm, nominal.y_mm, nominal.table_z_mm + 300.0
        poses = calibration_poses(Pose(cx, cy, cz, 0.0, 180.0, 0.0), args.views, spread_mm=args.spread_mm,
                                  tilt_deg=args.tilt_deg, seed=args.seed)
        check_poses(poses, min_z_mm=nominal.table_z_mm + 100.0)
        from aioadept.bus.endpoints import opposite, parse_endpoint

        request = args.request_endpoint or opposite(cfg.vision.request_endpoint)
        response = args.response_endpoint or opposite(cfg.vision.response_endpoint)
        parse_endpoint(request)
        parse_endpoint(response)
        if args.write is not None and not args.write.parent.is_dir():
            raise ValueError(f"--write {args.write}: no folder {args.write.parent} to write it in; nothing was moved")
        if args.write is not None and args.write.exists():
            from aioadept.cell.schema import load_toml

            load_toml(args.write)  # a file we would rewrite must be TOML now: one line, before any motion
    except (OSError, ValueError, CalibrationError) as exc:
        return report(PROG, exc, verbose=args.verbose)
    except Exception as exc:  # BusError from an endpoint: one line too
        from aioadept.errors import AdeptError

        if isinstance(exc, AdeptError):
            return report(PROG, exc, verbose=args.verbose)
        raise
    from aioadept.apps.interrupt import run_interruptible

    runs: list = []
    try:
        # Ctrl-C, SIGTERM, SIGHUP: stop the arm first (written in the signal callback, its ack awaited), start no
        # motion, exit 130 (1 if the stop was not confirmed), as the focus app does.
        if start_sim or start_vision:  # the started cell opens (and closes) this process's Zenoh session
            cfg.robot.start_sim, cfg.vision.start = start_sim, start_vision
            code = run_interruptible(lambda intr: _run_in_cell(intr, runs, host, port, request, response, poses,
                                                               nominal, args, cfg), prog=PROG)
        else:
            with zenoh_session(cfg, "calibrate"):
                code = run_interruptible(lambda intr: _run(intr, runs, host, port, request, response, poses,
                                                           nominal, args, cfg), prog=PROG)
    except Exception as exc:  # the run failed: one line, the robot stays where it is
        if args.verbose:
            raise
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 1
    if code != 0 or not runs:
        return code or 1
    run = runs[0]
    cal = run.calibration
    print(cal.to_toml(), end="")
    log.info("%d views (%d skipped), rms %.3f px; camera at (%.1f, %.1f, %.1f) mm", len(run.views),
             len(run.skipped), cal.rms_px or 0.0, cal.x_mm, cal.y_mm, cal.z_mm)
    if args.write is not None:
        from aioadept.vision.calibration import write_calibration

        try:
            write_calibration(args.write, cal)
        except OSError as exc:
            print(f"{PROG}: cannot write {args.write}: {exc}", file=sys.stderr)
            return 1
    return 0


def _starts(args: argparse.Namespace, cfg) -> tuple[bool, bool]:  # noqa: ANN001
    """Whether to start the sim and the vision node: what the cell file (``--config``) says this machine starts,
    unless the command line names the node to use. A started vision node must be one calibration can use: the world
    camera's part locator, with a marker on the tool (else a ConfigError, before anything starts)."""
    from aioadept.errors import ConfigError

    if args.config is None:
        return False, False
    start_sim = cfg.robot.start_sim and not args.robot
    start_vision = cfg.vision.start and not (args.request_endpoint or args.response_endpoint)
    if start_vision and not (cfg.vision.graph == "locate" and "world" in cfg.vision.sources()
                             and cfg.world is not None and cfg.world.tool_marker is not None):
        raise ConfigError(f'{args.config}: the vision node it starts cannot see a marker on the tool: calibration '
                          f'needs [vision] graph = "locate", source = "world" and a [world.tool_marker] table '
                          f'(examples/pickplace-cell.toml has them), or --request-endpoint/--response-endpoint of '
                          f'a locator node already running')
    return start_sim, start_vision


async def _run_in_cell(intr, runs, host, port, request, response, poses, nominal, args, cfg) -> int:  # noqa: ANN001
    """Start the cell's nodes (:func:`aioadept.apps.cell.running_cell`), run the calibration against them, stop
    them; a node that dies ends the run (:meth:`aioadept.apps.cell.Cell.run`)."""
    import dataclasses

    from aioadept.apps.cell import new_run_dir, running_cell, stop_port_of
    from aioadept.bus.endpoints import opposite

    run_dir = new_run_dir(dataclasses.replace(cfg, run=dataclasses.replace(cfg.run, name="calibrate")))
    log.info("starting the cell's %s; logs in %s", " and ".join(
        n for n, on in (("sim", cfg.robot.start_sim), ("vision node", cfg.vision.start)) if on), run_dir / "logs")
    async with running_cell(cfg, run_dir / "logs") as cell:
        c = cell.cfg
        if c.robot.start_sim:
            host, port = c.robot.host, c.robot.port
        if c.vision.start:
            request, response = opposite(c.vision.request_endpoint), opposite(c.vision.response_endpoint)
        stop_port = stop_port_of(c) if c.robot.start_sim else "auto"
        return await cell.run(_run(intr, runs, host, port, request, response, poses, nominal, args, c,
                                   stop_port=stop_port))


async def _run(intr, runs, host, port, request, response, poses, nominal, args, cfg,  # noqa: ANN001
               stop_port: int | str = "auto") -> int:
    from aioadept.apps.calibrate import calibrate
    from aioadept.bus.communicator import Communicator
    from aioadept.client.robot import RobotClient

    async with RobotClient(host, port, connect_timeout_s=cfg.robot.connect_timeout_s,
                           ack_timeout_s=cfg.robot.ack_timeout_s, stop_port=stop_port) as robot, intr.guard(robot), \
            Communicator(request, response, timeout_s=args.vision_timeout, queries=cfg.bus.zenoh_queries) as comm:
        runs.append(await calibrate(robot, comm, poses, nominal, marker=args.marker, marker_mm=args.marker_mm,
                                    speed=args.speed, vision_timeout_s=args.vision_timeout))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
