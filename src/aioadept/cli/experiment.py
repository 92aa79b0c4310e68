"""``aioadept experiment``: the paper's experiment — focus runs over a grid of approach speed x delta_z, N each.

The nodes are started once; each run gets its own run folder; the analysis then pools all runs (the paper pooled
32 runs over speed {5, 25, 50, 75, 100} x delta_z {1.5, 2.0, 2.5}). Ctrl-C stops the robot and ends the whole
experiment (no further run starts); a second Ctrl-C kills the nodes and exits at once.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from aioadept.cell.config import CellConfig
from aioadept.apps.experiment import run_experiment
from aioadept.apps.interrupt import Interrupter, run_interruptible
from aioadept.cli.options import (
    ArgumentParser,
    add_config,
    add_verbose,
    check_option,
    configure_logging,
    description,
)
from aioadept.cell.schema import report

log = logging.getLogger("aioadept.experiment")


def _floats(option: str, text: str) -> list[float]:
    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"{option} {text!r}: expected comma-separated numbers") from None
    if not values:
        raise ValueError(f"{option} {text!r}: expected at least one value")
    return values


def grid_of(args: argparse.Namespace) -> list[tuple[int, float]]:
    """The (speed, delta_z) grid of ``--speeds`` x ``--delta-z``, every value checked against the range of its
    :class:`~aioadept.apps.focus.FocusParams` field; ValueError naming the option."""
    from aioadept.apps.focus import FocusParams

    speeds = _floats("--speeds", args.speeds)
    steps = _floats("--delta-z", args.delta_z)
    for s in speeds:
        check_option("--speeds", FocusParams, "approach_speed", s)
    for dz in steps:
        check_option("--delta-z", FocusParams, "delta_z_mm", dz)
    if args.runs < 1:
        raise ValueError(f"--runs {args.runs}: expected an integer >= 1")
    return [(int(s), dz) for s in speeds for dz in steps]


def build_parser() -> argparse.ArgumentParser:
    from aioadept.apps.focus import FocusParams
    from aioadept.cell.schema import range_of

    p = ArgumentParser(prog="aioadept experiment", description=description(__doc__))
    add_config(p, "cell description (TOML)", type=Path)
    speeds, steps = range_of(FocusParams, "approach_speed").text, range_of(FocusParams, "delta_z_mm").text
    p.add_argument("--speeds", default="5,25,50,75,100",
                   help=f"approach speeds, each {speeds} (default: the paper's)".replace("%", "%%"))
    p.add_argument("--delta-z", dest="delta_z", default="1.5,2.0,2.5", metavar="MM[,MM...]",
                   help=f"z steps, each {steps} (default: the paper's)")
    p.add_argument("--runs", type=int, default=2, help="runs per grid point, >= 1 (default 2)")
    p.add_argument("--time-scale", type=float, dest="time_scale", default=None, help="sim motion speed-up")
    p.add_argument("--out", default=None, metavar="DIR", help="experiment folder (default runs/experiment-<time>)")
    add_verbose(p)
    from aioadept.record.hook import add_view_options

    add_view_options(p)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    configure_logging(args.verbose)
    try:
        cfg = CellConfig.from_toml(args.config) if args.config else CellConfig()
    except (OSError, ValueError) as exc:
        return report("aioadept experiment", exc, verbose=args.verbose)
    if not args.config:
        cfg.robot.port = 0
        cfg.robot.state_endpoint = cfg.vision.request_endpoint = cfg.vision.response_endpoint = "tcp://127.0.0.1:0"
    try:
        grid = grid_of(args)
        if args.time_scale is not None:
            check_option("--time-scale", type(cfg.robot), "time_scale", args.time_scale)
    except ValueError as exc:
        return report("aioadept experiment", exc, verbose=args.verbose)
    if args.time_scale is not None:
        cfg.robot.time_scale = args.time_scale
    from aioadept.record.hook import refuse_view_without_rerun

    if refuse_view_without_rerun(args, "aioadept experiment"):
        return 2
    import datetime as _dt

    out = Path(args.out or Path(cfg.run.out_dir) / f"experiment-{_dt.datetime.now():%Y%m%d-%H%M%S}")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        print(f"aioadept experiment: cannot create {str(out)!r}: {exc}; nothing was started", file=sys.stderr)
        return 2
    from aioadept.record.hook import keep_frames, run_with_viewer

    cfg.run.record = not args.no_record
    keep_frames(cfg, args, out / "frames")  # frames for each run's run.rrd and the live view
    return run_with_viewer(args, "aioadept experiment", cfg, out / "logs" / "viewer.log",
                           lambda: _run(cfg, grid, args.runs, out))


def _run(cfg: CellConfig, grid: list[tuple[int, float]], runs: int, out: Path) -> int:
    results: list[list[Path]] = []

    async def app(intr: Interrupter) -> int:
        results.append(await run_experiment(cfg, grid, runs, out, interrupter=intr))
        return 0

    try:
        code = run_interruptible(app, prog="aioadept experiment")
    except Exception as exc:  # one line on stderr, as demo and focus
        from aioadept.cli.report import failure_line

        print(failure_line("aioadept experiment", exc, out), file=sys.stderr)
        return 1
    if code:
        return code
    run_dirs = results[0]
    if not run_dirs:
        print(f"aioadept experiment: no run was saved whole: each failed or could not write its tables (logs in {out})",
              file=sys.stderr)
        return 1
    from aioadept.analysis import analyze_runs
    from aioadept.apps.interrupt import EXIT_INTERRUPTED, interrupt_handled
    from aioadept.cli.report import stop_signals_interrupt

    try:
        with stop_signals_interrupt():
            analyze_runs(run_dirs, out / "analysis")
    except KeyboardInterrupt:  # the runs are saved; the analysis writes nothing half
        interrupt_handled()
        if (out / "analysis" / "summary.json").is_file():  # the interrupt came as it was ending: it is whole
            done = "its analysis was written"
        else:
            done = f"its analysis was not written: redo it with `aioadept analyze {out} --out {out / 'analysis'}`"
        print(f"aioadept experiment: interrupted during the analysis: the runs are kept in {out}; {done}",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    except (OSError, ValueError) as exc:
        print(f"aioadept experiment: the runs are saved in {out}, but the analysis was not (fully) written: {exc}",
              file=sys.stderr)
        return 4
    log.info("analysis of %d runs written to %s", len(run_dirs), out / "analysis")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
