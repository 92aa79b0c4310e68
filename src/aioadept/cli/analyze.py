"""``aioadept analyze RUN_DIR...``: the paper's timing metrics, fits and figures for one or many recorded runs.

Exit codes: 0 analysed; 1 no complete approach iteration in the runs (outputs are still written, with n = 0);
2 bad arguments, or no readable run in any path (paths without one are skipped with a note); 4 outputs not written
(disk full, ...: each named); 130 interrupted (the folder keeps its previous analysis).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["main"]

EXIT_NOT_SAVED = 4
"""Exit code when outputs of the analysis could not be written (named on stderr), as ``demo``/``focus``'s 4."""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="aioadept analyze",
        description="Compute the paper's timing quantities (tau_r, switching durations; eqs. 1-5) over run folders "
                    "written by aioadept.runs.capture, pool them across runs, fit their distributions and write "
                    "figures like the paper's Figs. 9-13, summary.json and iterations.csv: into the run folder for one "
                    "run, into ./analysis/ (created in the current folder) for several, unless --out. Folders "
                    "without a run (e.g. the logs a failed demo leaves) are skipped with a note.",
        epilog="Exit codes: 0 analysed; 1 no complete approach iteration (outputs still written); 2 no readable "
               "run in any path, or bad arguments; 4 outputs not written (each named); 130 interrupted. "
               "See docs/analysis.md.")
    p.add_argument("run_dirs", nargs="+", metavar="RUN_DIR",
                   help="a run folder (with run.json), or a folder whose subfolders are runs")
    p.add_argument("--out", metavar="DIR", default=None,
                   help="output folder (default: the run folder for one run, ./analysis for several)")
    p.add_argument("--no-plots", action="store_true", help="skip the figures (stats and summary only)")
    p.add_argument("--gantt-first", type=int, default=1, metavar="K",
                   help="first complete iteration shown in the Gantt chart (default 1, as i >= 1 has tau r->v)")
    p.add_argument("--gantt-count", type=int, default=2, metavar="N",
                   help="number of iterations in the Gantt chart (default 2, as the paper's Fig. 10)")
    p.add_argument("--no-rrd", action="store_true",
                   help="do not write run.rrd (the Rerun recording rebuilt from the CSV logs) into each run folder")
    p.add_argument("--group-by", default="approach_speed,delta_z_mm", metavar="KEYS",
                   help="comma-separated run parameters to split the stats by in summary.json "
                        "(default: approach_speed,delta_z_mm; '' for none)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    from rich.console import Console

    from aioadept.analysis.report import analyze_runs, fits_table, summary_table
    from aioadept.errors import AnalysisSaveError
    from aioadept.apps.interrupt import interrupt_handled
    from aioadept.cli.report import stop_signals_interrupt

    console = Console()
    args.run_dirs = _with_runs(args.run_dirs)
    if not args.run_dirs:
        print("aioadept analyze: no run folder (run.json) in any of the paths given", file=sys.stderr)
        return 2
    not_saved = None
    try:
        with stop_signals_interrupt():  # Ctrl-C, SIGTERM, SIGHUP: one line, the previous analysis kept
            summary = analyze_runs(args.run_dirs, args.out, plots=not args.no_plots, gantt_first=args.gantt_first,
                                   gantt_count=args.gantt_count,
                                   group_by=[k for k in args.group_by.split(",") if k.strip()])
    except AnalysisSaveError as exc:  # the analysis is done; some of its files are not on disk (named)
        if exc.summary is None:
            print(f"aioadept analyze: {exc}", file=sys.stderr)
            return EXIT_NOT_SAVED
        summary, not_saved = exc.summary, exc
    except (FileNotFoundError, ValueError) as exc:
        print(f"aioadept analyze: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"aioadept analyze: the analysis was not written: {exc}", file=sys.stderr)
        return EXIT_NOT_SAVED
    except KeyboardInterrupt:
        interrupt_handled()
        print("aioadept analyze: interrupted: the analysis was not written (a previous one stays as it was)",
              file=sys.stderr)
        return 130
    if not args.no_rrd:
        _write_rrds(args.run_dirs, console)
    console.print(summary_table(summary))
    console.print(fits_table(summary))
    if len(summary.runs) <= 8:  # beyond that the list drowns the table; summary.json has every run
        for run in summary.runs:
            # Scalars only: a run's parameters may hold whole cell configurations and results.
            params = ", ".join(f"{k}={v}" for k, v in run.parameters.items()
                               if isinstance(v, (int, float, bool)) or (isinstance(v, str) and len(v) <= 24))
            console.print(f"  {run.name}: {run.n_complete}/{run.n_iterations} complete iterations  {params}",
                          markup=False, highlight=False)
    console.print(f"wrote {', '.join(sorted(p.name for p in summary.files.values()))} to {summary.out_dir}",
                  markup=False, highlight=False)
    if not_saved is not None:
        print(f"aioadept analyze: {not_saved}", file=sys.stderr)
        return EXIT_NOT_SAVED
    if summary.n_complete == 0:
        print("aioadept analyze: no complete approach iteration (vision request + set_speed/move_rel_tool/break) "
              "in these runs", file=sys.stderr)
        return 1
    return 0


def _with_runs(paths: list[str]) -> list[str]:
    """The paths that hold a run (``run.json`` here or below); each other one is skipped with a one-line note, so
    ``analyze runs/*`` works beside the logs-only folder a failed demo leaves."""
    kept = []
    for p in paths:
        path = Path(p)
        if (path / "run.json").is_file() or (path.is_dir() and next(path.rglob("run.json"), None) is not None):
            kept.append(p)
        else:
            why = "no such folder" if not path.exists() else "no run.json here or below (e.g. a failed run's logs)"
            print(f"aioadept analyze: skipping {p}: {why}", file=sys.stderr)
    return kept


def _write_rrds(run_dirs: list[str], console) -> None:  # noqa: ANN001
    """run.rrd for every analysed run folder that has none yet (a live run's own, with the robot-state stream and
    the frames, is kept); see docs/record.md. Skipped without the [viewer] extra."""
    from aioadept.record import rerun_available

    if not rerun_available():
        return
    from aioadept.analysis.report import expand_run_dirs
    from aioadept.record.from_csv import rrd_from_run

    for path in expand_run_dirs(run_dirs):
        if (path / "run.rrd").exists():
            continue
        try:
            rrd_from_run(path)
            console.print(f"wrote {path / 'run.rrd'}", markup=False, highlight=False)
        except (OSError, ValueError) as exc:
            print(f"aioadept analyze: no run.rrd for {path}: {exc}", file=sys.stderr)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
