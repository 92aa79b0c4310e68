"""``aioadept calibrate``: estimate the fixed camera's pose in the robot base frame from views of an ArUco marker on
the tool, and print (or write into a cell file) the ``[calibration]`` table the part locator uses.

Nothing is started here, only connected to: a robot server (the sim or a real controller) and a vision node serving
the part locator (``aioadept vision --graph locate``). The robot moves ``move_to`` + ``break`` through ``--views``
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
from aioadept.cli.options import (ArgumentParser, add_robot_option, add_verbose, description, parse_robot_address,
                                  report, with_default)
from aioadept.configfile import Range

log = logging.getLogger("aioadept.calibrate")

PROG = "aioadept calibrate"
RANGES = {"views": Range(3, 200, integer=True), "marker": Range(0, 999, integer=True),
          "marker_mm": Range(1.0, 500.0, unit="mm"), "speed": Range(1, 100, integer=True),
          "spread_mm": Range(0.0, 500.0, unit="mm"), "tilt_deg": Range(0.0, 45.0, unit="deg"),
          "vision_timeout": Range(0.0, 600.0, lo_open=True, unit="s")}


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog=PROG, description=description(__doc__))
    p.add_argument("--config", type=Path, help="cell file: robot address, vision endpoints, [bus] (on Zenoh: the "
                                                "cell's keys and router), the nominal "
                                                "[calibration] (intrinsics, table); defaults without it")
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
    p.add_argument("--marker", type=int, default=0, help="ArUco id of the marker on the tool (default 0)")
    p.add_argument("--marker-mm", type=float, default=40.0, help="its side, black border included (default 40)")
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
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    from aioadept.apps.calibrate import CalibrationError, calibration_poses, check_poses
    from aioadept.apps.cell import CellConfig
    from aioadept.apps.cellbus import with_transport, zenoh_session
    from aioadept.geometry import Pose
    from aioadept.vision.calibration import CameraCalibration

    try:
        for key, rng in RANGES.items():
            rng.check("--" + key.replace("_", "-"), getattr(args, key), sep=" ")
        # [bus] transport = "zenoh": the vision node's requests on the cell's keys, through the cell's router
        cfg = with_transport(CellConfig.from_toml(args.config) if args.config else CellConfig())
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
        if args.write is not None and args.write.exists():
            from aioadept.configfile import load_toml

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
        with zenoh_session(cfg, "calibrate"):
            code = run_interruptible(lambda intr: _run(intr, runs, host, port, request, response, poses, nominal,
                                                       args, cfg), prog=PROG)
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


async def _run(intr, runs, host, port, request, response, poses, nominal, args, cfg) -> int:  # noqa: ANN001
    from aioadept.apps.calibrate import calibrate
    from aioadept.bus.communicator import Communicator
    from aioadept.client.robot import RobotClient

    async with RobotClient(host, port, connect_timeout_s=cfg.robot.connect_timeout_s,
                           ack_timeout_s=cfg.robot.ack_timeout_s) as robot, intr.guard(robot), \
            Communicator(request, response, timeout_s=args.vision_timeout, queries=cfg.bus.zenoh_queries) as comm:
        runs.append(await calibrate(robot, comm, poses, nominal, marker=args.marker, marker_mm=args.marker_mm,
                                    speed=args.speed, vision_timeout_s=args.vision_timeout))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
