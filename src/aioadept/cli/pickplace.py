"""``aioadept pickplace``: vision-guided pick and place, parts from the feeder to the pallet's slots.

Without --config it starts the example cell (examples/pickplace-cell.toml: the sim with a world of parts and the
vision node with its part locator) on free ports; a cell file says itself which nodes run here (start_sim = false:
a real controller). Every option and cell value is checked before anything starts (exit 2, one line). Ctrl-C (or
SIGTERM/SIGHUP) stops the robot where it is, then the nodes (exit 130).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
from pathlib import Path

from aioadept.cli.options import ArgumentParser, add_verbose, configure_logging, description

log = logging.getLogger("aioadept.pickplace")

EXAMPLE_CELL = Path(__file__).resolve().parents[3] / "examples" / "pickplace-cell.toml"
VPLUS_DIR = Path(__file__).resolve().parents[3] / "vplus"
PROG = "aioadept pickplace"


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog=PROG, description=description(__doc__))
    p.add_argument("--config", type=Path, metavar="FILE", help=f"cell file (TOML; default {EXAMPLE_CELL.name} of the examples)")
    p.add_argument("--parts", type=int, help="parts to pick and place ([pickplace] parts)")
    p.add_argument("--speed", type=int, help="program speed of every motion, %% ([pickplace] speed)")
    p.add_argument("--part-timeout", type=float, dest="part_timeout",
                   help="seconds to wait for a part on the feeder ([pickplace] part_timeout_s)")
    p.add_argument("--time-scale", type=float, dest="time_scale", help="sim only: motion speed-up")
    p.add_argument("--fast", action="store_true", help="same as --time-scale 10")
    p.add_argument("--vplus", nargs="*", metavar="FILE", default=None,
                   help="run V+ modules on the V+ emulator instead of the Python sim, task 0 running rs.main: the "
                        "controller's own V+ server (vplus/) unless these files are named")
    p.add_argument("--out", metavar="DIR", help="folder for run folders (default: runs)")
    add_verbose(p)
    return p


def pickplace_config(args: argparse.Namespace):  # noqa: ANN201
    """The cell of ``args``; ValueError/OSError (one line naming the file, key or option) for anything bad."""
    from aioadept.cell.config import CellConfig
    from aioadept.apps.pickplace import PickPlaceParams
    from aioadept.cell.schema import range_of

    path = args.config or EXAMPLE_CELL
    cfg = CellConfig.from_toml(path)
    changes = {}
    for opt, dest, name in (("--parts", "parts", "parts"), ("--speed", "speed", "speed"),
                            ("--part-timeout", "part_timeout", "part_timeout_s")):
        value = getattr(args, dest)
        if value is not None:
            range_of(PickPlaceParams, name).check(opt, value, sep=" ")
            changes[name] = value
    try:
        cfg.pickplace = dataclasses.replace(cfg.pickplace, **changes)
    except ValueError as exc:
        raise ValueError(f"{path} [pickplace]: {exc}") from None
    if args.fast:
        cfg.robot.time_scale = 10.0
    if args.time_scale is not None:
        range_of(type(cfg.robot), "time_scale").check("--time-scale", args.time_scale, sep=" ")
        cfg.robot.time_scale = args.time_scale
    if args.out:
        cfg.run.out_dir = args.out
    w = cfg.world
    if w is None or w.pallet is None:
        raise ValueError(f"{path}: no [world.pallet]: pick and place needs the pallet's slots")
    p = cfg.pickplace
    if p.first_slot + p.parts > w.pallet.slots:
        raise ValueError(f"{path}: {p.parts} parts from slot {p.first_slot} need {p.first_slot + p.parts} pallet "
                         f"slots; [world.pallet] has {w.pallet.slots} ({w.pallet.rows} x {w.pallet.cols})")
    if w.feeder is not None and w.feeder.sensor != p.part_sensor:
        raise ValueError(f"{path} [pickplace]: part_sensor = {p.part_sensor}: the feeder's sensor is input "
                         f"{w.feeder.sensor} ([world.feeder] sensor)")
    from aioadept.apps.pickplace import slot_targets
    from aioadept.errors import PickPlaceError

    try:  # every slot inside the workspace, before anything starts
        slot_targets(w.pallet, p, w.table_z_mm + 1.0)
    except PickPlaceError as exc:
        raise ValueError(f"{path}: {exc}") from None
    if args.vplus is not None:
        if not cfg.robot.start_sim:
            raise ValueError("--vplus: the cell file says start_sim = false (no sim is started here)")
        modules = args.vplus or [str(VPLUS_DIR / name) for name in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]
        cfg.robot.sim_args = ["--vplus", *modules, "--run", "rs.main", *cfg.robot.sim_args]
    return cfg


def main(argv: list[str] | None = None) -> int:
    """Exit codes: 0 every part placed; 1 the run failed (a fault, or a stop failed); 2 bad options or cell file
    (nothing started, no run folder); 130 interrupted with the robot stopped."""
    args = build_parser().parse_args(argv)
    configure_logging(args.verbose)
    from aioadept.cell.schema import report

    try:
        cfg = pickplace_config(args)
    except (OSError, ValueError) as exc:
        return report(PROG, exc, verbose=args.verbose)
    from aioadept.apps.cell import new_run_dir

    cfg.run.name = cfg.run.name or f"pickplace-n{cfg.pickplace.parts}-s{cfg.pickplace.speed}"
    try:
        run_dir = new_run_dir(cfg)
    except OSError as exc:
        print(f"{PROG}: cannot create a run folder in {cfg.run.out_dir!r}: {exc}; nothing was started",
              file=sys.stderr)
        return 2
    return run(cfg, run_dir)


def run(cfg, run_dir: Path, locator=None) -> int:  # noqa: ANN001
    """Start the cell's nodes, pick and place, stop the nodes; print the outcome; the exit code."""
    import json

    from aioadept.apps.cell import running_cell
    from aioadept.apps.interrupt import run_interruptible
    from aioadept.apps.pickplace_run import run_pickplace_once
    from aioadept.cli.report import failure_line

    async def app(intr) -> int:  # noqa: ANN001
        async with running_cell(cfg, run_dir / "logs") as cell:
            await cell.run(run_pickplace_once(cell.cfg, run_dir, interrupter=intr, locator=locator))
        return 0

    try:
        code = run_interruptible(app, prog=PROG)
    except Exception as exc:
        print(failure_line(PROG, exc, run_dir), file=sys.stderr)
        return 1
    if code == 0:
        try:
            s = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
            err = max(s["place_error_mm"], default=float("nan"))
            print(f"{s['parts_placed']} of {s['parts']} parts placed; largest place error {err:.2f} mm; median "
                  f"cycle/floor {s['median_cycle_over_floor']}; run folder {run_dir}")
        except (OSError, ValueError, KeyError) as exc:
            print(f"{PROG}: summary.json unreadable ({exc}); run folder {run_dir}", file=sys.stderr)
            return 4
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
