"""The paper's experiment: focus runs over a grid of approach speed x delta_z, N each (``aioadept experiment``).

The nodes are started once; each run gets its own run folder; the analysis then pools all runs (the paper pooled
32 runs over speed {5, 25, 50, 75, 100} x delta_z {1.5, 2.0, 2.5}). Ctrl-C stops the robot and ends the whole
experiment (no further run starts); a second Ctrl-C kills the nodes and exits at once.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
from pathlib import Path

from aioadept.apps.cell import new_run_dir, run_focus_once, running_cell
from aioadept.cell.config import CellConfig
from aioadept.apps.interrupt import Interrupter

log = logging.getLogger("aioadept.experiment")


async def run_experiment(cfg: CellConfig, grid: list[tuple[int, float]], runs: int, out: Path, *,
                         interrupter: Interrupter | None = None) -> list[Path]:
    """Run the grid against nodes started once; returns the run folders that are complete (their tables and
    ``run.json`` written; a file that failed besides them, e.g. ``run.rrd`` on a full disk, is named in ``run.json``
    and logged)."""
    from rich.progress import Progress

    from aioadept.runs.capture import note_not_written
    from aioadept.errors import RunSaveError

    done: list[Path] = []
    failures = 0
    async with running_cell(cfg, out / "logs") as cell:
        with Progress() as progress:
            task = progress.add_task("focus runs", total=len(grid) * runs)
            for (speed, dz), k in itertools.product(grid, range(runs)):
                params = dataclasses.replace(cell.cfg.focus, approach_speed=speed, delta_z_mm=dz)
                cell.cfg.run.name = f"s{speed}-dz{dz:g}-{k}"
                run_dir = new_run_dir(cell.cfg, out)
                try:
                    outcome = await cell.run(run_focus_once(cell.cfg, run_dir, params=params,
                                                            interrupter=interrupter))
                except Exception as exc:  # keep going: a failed run is data too, and is logged in its folder
                    failures += 1
                    log.error("run %s failed: %s", run_dir.name, exc)
                else:
                    complete = (run_dir / "run.json").is_file()  # its tables are whole: the analysis can use it
                    if outcome.save_error is not None:
                        # e.g. only run.rrd cut short by a full disk: named in run.json, the run still counts
                        if complete and isinstance(outcome.save_error, RunSaveError):
                            note_not_written(run_dir, outcome.save_error.not_written)
                        log.error("run %s found the inspection pose %s but %s", run_dir.name,
                                  outcome.result.inspection_pose if outcome.result else None, outcome.save_error)
                    if complete:
                        done.append(run_dir)
                    else:  # the result is in the log line; the folder is incomplete, so the analysis leaves it out
                        failures += 1
                progress.advance(task)
    log.info("%d runs done, %d failed", len(done), failures)
    return done
