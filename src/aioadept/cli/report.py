"""The terminal report of a focus run (``demo``, ``focus``): the sharpness table, the found pose, and what was not
saved."""

from __future__ import annotations

import contextlib
import logging
import signal
import sys
from collections.abc import Awaitable, Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from aioadept.apps.paper import FocusResult
    from aioadept.apps.interrupt import Interrupter

log = logging.getLogger(__name__)


def print_result(result: FocusResult, run_dir: Path) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    if result.mode == "sweep":
        _print_sweep(console, result, run_dir)
        return
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


def _print_sweep(console: Any, result: FocusResult, run_dir: Path) -> None:
    """A sweep's frames (position along tool z, sharpness) and the fitted plane with its uncertainty."""
    from rich.table import Table

    frames = [f for f in result.frames if f.get("offset_mm") is not None]
    top = max((f["sharpness"] for f in frames), default=1.0) or 1.0
    table = Table(title="Sharpness along tool z, one sweep", show_lines=False)
    for col in ("sweep", "z offset (mm)", "sharpness", ""):
        table.add_column(col, justify="right" if col else "left")
    for f in frames:
        table.add_row(str(f["sweep"]), f"{f['offset_mm']:.2f}", f"{f['sharpness']:.2f}",
                      "█" * max(1, round(30 * f["sharpness"] / top)))
    console.print(table)
    sigma = f" ± {result.peak_sigma_mm:.3f}" if result.peak_sigma_mm is not None else ""
    search = f", found {result.search_s:.3f} s after the sweep started" if result.search_s is not None else ""
    console.print(f"[bold]focal plane[/bold] {result.peak_offset_mm:.3f}{sigma} mm along tool z from the approach "
                  f"pose (fitted; frames placed by the {result.pose_source}{search}); the robot is there:")
    p = result.inspection_pose
    console.print(f"  x={p.x:.3f} y={p.y:.3f} z={p.z:.3f} mm  yaw={p.yaw:.3f} pitch={p.pitch:.3f} "
                  f"roll={p.roll:.3f} deg")
    console.print(f"run folder: {run_dir}")


EXIT_NOT_SAVED = 4
"""Exit code when the result was found and printed but files of the run folder (or its analysis) were not written."""


def report_saving(outcome: Any, *, analyze: bool, prog: str) -> int:
    """After a successful run whose result is printed: analyse the run, then say on stderr what was not written.

    The analysis runs when the run folder is complete (``run.json`` written), whatever else failed. Every output
    not written (the run's files, the vision node's ``frames/frames.csv``, the analysis's figures:)
    is named, with its reason, in one line on stderr and in ``run.json``'s ``not_written``. Returns 0, or
    :data:`EXIT_NOT_SAVED`.
    """
    from aioadept.runs.capture import note_not_written
    from aioadept.errors import RunSaveError

    run_dir = Path(outcome.run_dir)
    err = outcome.save_error
    not_written: dict[str, str] = {}
    if isinstance(err, RunSaveError):
        not_written.update(err.not_written)
    elif err is not None:
        not_written["run folder"] = str(err)
    complete = "run.json" not in not_written and (run_dir / "run.json").is_file()
    if analyze and complete:
        from aioadept.analysis.report import analyze_runs
        from aioadept.errors import AnalysisSaveError

        try:
            analyze_runs([run_dir], run_dir)
        except AnalysisSaveError as exc:
            not_written.update(exc.not_written)
        except (OSError, ValueError) as exc:
            not_written["analysis"] = f"{type(exc).__name__}: {exc}" if isinstance(exc, ValueError) else (
                exc.strerror or str(exc))
    elif analyze:
        not_written["analysis"] = f"not made: the run folder is incomplete; `aioadept analyze {run_dir}` once it is"
    if not not_written:
        return 0
    listed = complete and note_not_written(run_dir, not_written)
    parts = "; ".join(f"{name} ({why})" for name, why in not_written.items())
    tail = "" if listed or not complete else "; run.json could not be updated to list them"
    print(f"{prog}: the result above was found but NOT fully saved: run folder {run_dir}: not written: {parts}{tail}",
          file=sys.stderr)
    return EXIT_NOT_SAVED


@contextlib.contextmanager
def stop_signals_interrupt() -> Iterator[None]:
    """After the run (the robot's connection is closed): SIGINT, SIGTERM and SIGHUP raise KeyboardInterrupt, so
    that each gets the one line of :func:`run_once`, not a traceback or a silent death mid-file.

    An interrupt is never lost: Python raises it wherever the main thread happens to be, and one raised inside a
    ``__del__`` run by the garbage collector (a ZeroMQ socket's, seen in 1 of 6 runs) is only printed as "ignored";
    so a signal seen by the handler raises KeyboardInterrupt again when the block ends without one.
    """
    seen: list[int] = []

    def interrupt(signum: int, _frame: Any) -> None:
        seen.append(signum)
        raise KeyboardInterrupt

    def unraisable(info: Any) -> None:  # the swallowed interrupt is raised again below: no traceback for it
        if not (seen and isinstance(info.exc_value, KeyboardInterrupt)):
            hook(info)

    saved = {}
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        with contextlib.suppress(ValueError, OSError):  # not the main thread: leave them as they are
            saved[sig] = signal.signal(sig, interrupt)
    hook, sys.unraisablehook = sys.unraisablehook, unraisable
    try:
        yield
        if seen:
            raise KeyboardInterrupt
    finally:
        sys.unraisablehook = hook
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def failure_line(prog: str, exc: BaseException, run_dir: Path) -> str:
    """The one line a failed run prints on stderr (never wrapped, never split): what failed, and where its log is
    while the run folder exists (a run whose robot connection never succeeded leaves none)."""
    from aioadept.errors import ConnectError

    what = str(exc) if isinstance(exc, ConnectError) else f"{type(exc).__name__}: {exc}"
    where = f" (log in {run_dir})" if run_dir.exists() else ""
    return " ".join(f"{prog} failed: {what}{where}".split())


def run_once(app: Callable[[Interrupter], Awaitable[Any]], run_dir: Path, *, analyze: bool, prog: str) -> int:
    """Run one focus run (``app(interrupter)`` returns its :class:`~aioadept.apps.cell.RunOutcome`) with the
    Ctrl-C policy, print its result, then :func:`report_saving`. Returns the exit code (``focus``/``demo``'s).

    Ctrl-C (or SIGTERM/SIGHUP) after the run, while its result is printed or the run analysed, gives one line: the
    run is kept and ``aioadept analyze RUN`` redoes the analysis (exit 130); the analysis writes nothing half.
    """
    from aioadept.apps.interrupt import EXIT_INTERRUPTED, interrupt_handled, run_interruptible

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
    try:
        with stop_signals_interrupt():
            print_result(outcome.result, run_dir)
            return report_saving(outcome, analyze=analyze, prog=prog)
    except KeyboardInterrupt:
        interrupt_handled()
        kept = "is kept" if outcome.save_error is None else "is kept, NOT fully saved,"
        if not analyze:
            redo = ""
        elif (run_dir / "summary.json").is_file():  # the interrupt came as the analysis was ending: it is whole
            redo = "; its analysis was written"
        else:
            redo = f"; its analysis was not written: redo it with `aioadept analyze {run_dir}`"
        with contextlib.suppress(OSError, ValueError):
            print(f"{prog}: interrupted after the run: the run {kept} in {run_dir} (result in focus.json){redo}",
                  file=sys.stderr, flush=True)
        return EXIT_INTERRUPTED
