"""The terminal report of a focus run (``demo``, ``focus``): the sharpness table, the found pose, and what was not
saved."""

from __future__ import annotations

import logging
import sys
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from aioadept.apps.focus import FocusResult
    from aioadept.apps.interrupt import Interrupter

log = logging.getLogger(__name__)


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


def failure_line(prog: str, exc: BaseException, run_dir: Path) -> str:
    """The one line a failed run prints on stderr (never wrapped, never split): what failed, and where its log is
    while the run folder exists (a run whose robot connection never succeeded leaves none)."""
    from aioadept.errors import ConnectError

    what = str(exc) if isinstance(exc, ConnectError) else f"{type(exc).__name__}: {exc}"
    where = f" (log in {run_dir})" if run_dir.exists() else ""
    return " ".join(f"{prog} failed: {what}{where}".split())


def run_once(app: Callable[[Interrupter], Awaitable[Any]], run_dir: Path, *, analyze: bool, prog: str) -> int:
    """Run one focus run (``app(interrupter)`` returns its :class:`~aioadept.apps.cell.RunOutcome`) with the
    Ctrl-C policy, print its result, then :func:`report_saving`. Returns the exit code (``focus``/``demo``'s)."""
    from aioadept.apps.interrupt import run_interruptible

    outcomes: list[Any] = []

    async def main(intr: Interrupter) -> int:
        outcomes.append(await app(intr))
        return 0

    try:
        code = run_interruptible(main, prog=prog)
    except Exception as exc:  # one clear line for the user, on stderr; details are in the run folder's logs
        print(failure_line(prog, exc, run_dir), file=sys.stderr)
        return 1
    if code or not outcomes:
        return code or 1
    outcome = outcomes[0]
    assert outcome.result is not None
    print_result(outcome.result, run_dir)
    return report_saving(outcome, analyze=analyze, prog=prog)
