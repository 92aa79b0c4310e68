"""Options shared by ``aioadept demo``, ``focus`` and ``experiment``, and the terminal report of a run."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

from aioadept.apps.cell import CellConfig
from aioadept.apps.focus import FocusResult


def add_cell_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", type=Path, help="cell description (TOML); options below override it")
    p.add_argument("--out", help="folder for run folders (default: runs)")
    p.add_argument("--speed", type=int, help="approach speed 0..100 (default 25)")
    p.add_argument("--delta-z", type=float, dest="delta_z", help="tool z step in mm (default 2.0)")
    p.add_argument("--max-steps", type=int, dest="max_steps", help="give up after this many steps (default 40)")
    p.add_argument("--vision-timeout", type=float, dest="vision_timeout", help="seconds per vision request")
    p.add_argument("--no-analyze", action="store_true", help="do not compute the timing analysis and plots")
    p.add_argument("-v", "--verbose", action="store_true")
    from aioadept.record.hook import add_view_options

    add_view_options(p)


def apply_overrides(cfg: CellConfig, args: argparse.Namespace) -> CellConfig:
    focus = cfg.focus
    if args.speed is not None:
        focus = dataclasses.replace(focus, approach_speed=args.speed)
    if args.delta_z is not None:
        focus = dataclasses.replace(focus, delta_z_mm=args.delta_z)
    if args.max_steps is not None:
        focus = dataclasses.replace(focus, max_steps=args.max_steps)
    if args.vision_timeout is not None:
        focus = dataclasses.replace(focus, vision_timeout_s=args.vision_timeout)
    cfg.focus = focus
    if args.out:
        cfg.run.out_dir = args.out
    if args.no_analyze:
        cfg.run.analyze = False
    if getattr(args, "no_record", False):
        cfg.run.record = False
    return cfg


def print_result(result: FocusResult, run_dir: Path) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    top = max(result.sharpness) or 1.0
    table = Table(title="Sharpness along tool z", show_lines=False)
    table.add_column("step", justify="right")
    table.add_column("z offset (mm)", justify="right")
    table.add_column("sharpness", justify="right")
    table.add_column("")
    for i, s in enumerate(result.sharpness):
        bar = "█" * max(1, round(30 * s / top))
        style = "bold red" if i == result.peak_index else ""
        table.add_row(str(i), f"{i * result.delta_z_mm:.1f}", f"{s:.2f}", bar, style=style)
    console.print(table)
    p = result.inspection_pose
    console.print(f"[bold]inspection-start pose[/bold] (step {result.peak_index}, "
                  f"{result.peak_offset_mm:.1f} mm along tool z from the approach pose):")
    console.print(f"  x={p.x:.3f} y={p.y:.3f} z={p.z:.3f} mm  yaw={p.yaw:.3f} pitch={p.pitch:.3f} "
                  f"roll={p.roll:.3f} deg")
    console.print(f"run folder: {run_dir}")


EXIT_NOT_SAVED = 4
"""Exit code when the result was found and printed but files of the run folder (or its analysis) were not written."""


def report_saving(outcome: Any, *, analyze: bool, prog: str) -> int:
    """After a successful run whose result is printed: say on stderr what was not written, and analyse the run.

    Returns 0, or :data:`EXIT_NOT_SAVED` with one line naming the files that could not be written.
    """
    if outcome.save_error is not None:
        print(f"{prog}: the result above was found but NOT fully saved: {outcome.save_error}", file=sys.stderr)
        return EXIT_NOT_SAVED
    if analyze:
        from aioadept.analysis import analyze_runs

        try:
            analyze_runs([outcome.run_dir], outcome.run_dir)
        except (OSError, ValueError) as exc:
            print(f"{prog}: the run is saved in {outcome.run_dir}, but its analysis was not written: {exc}",
                  file=sys.stderr)
            return EXIT_NOT_SAVED
    return 0


def configure_logging(verbose: bool) -> None:
    import logging

    from rich.logging import RichHandler

    logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO, format="%(message)s",
                        handlers=[RichHandler(show_path=False)])
