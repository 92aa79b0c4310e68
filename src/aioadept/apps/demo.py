"""The demo (``aioadept demo``): the whole simulated cell doing focus calibration, as separate processes on loopback.

It starts the simulated controller (``aioadept sim``) and the vision node with its virtual camera
(``aioadept vision``), runs the focus application in this process (the MasterControlNode), prints the found pose and
the sharpness curve, and writes a run folder: the timing log, the plots and a summary. Every node is stopped at the
end, also when a node fails. Ctrl-C stops the robot first, then the nodes; a second Ctrl-C kills them and exits at
once (:mod:`aioadept.apps.interrupt`).
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

from aioadept.apps.cell import RunOutcome, run_focus_once, running_cell
from aioadept.cell.config import CellConfig
from aioadept.runs.folder import merged_save_error
from aioadept.apps.interrupt import Interrupter

log = logging.getLogger("aioadept.demo")


async def run_demo(cfg: CellConfig, run_dir: Path, *, interrupter: Interrupter | None = None) -> RunOutcome:
    """Start the cell's nodes, run focus calibration once against them, stop the nodes; return the outcome."""
    async with running_cell(cfg, run_dir / "logs") as cell:
        log.info("robot server %s:%s, vision %s / %s", cell.cfg.robot.host, cell.cfg.robot.port,
                 cell.cfg.vision.request_endpoint, cell.cfg.vision.response_endpoint)
        outcome: RunOutcome = await cell.run(run_focus_once(cell.cfg, run_dir, interrupter=interrupter))
    return _with_frames_checked(cfg, run_dir, outcome)


def _with_frames_checked(cfg: CellConfig, run_dir: Path, outcome: RunOutcome) -> RunOutcome:
    """The vision node this demo started saves the frames it served into the run folder, in its own process; once
    it has stopped, a ``frames.csv`` missing there is a file not written (the node writes it whole or not at all:
    a full disk), added to the outcome's ``save_error`` so that it is named with the run's own files."""
    from aioadept.record.hook import frames_dir_of

    frames = frames_dir_of(cfg) if cfg.vision.start else None
    if frames is None or (frames / "frames.csv").is_file():
        return outcome
    try:
        name = (frames / "frames.csv").relative_to(run_dir).as_posix()
    except ValueError:
        name = str(frames / "frames.csv")
    why = "the vision node did not write it (a full disk, or the node was killed): see logs/vision.log"
    return dataclasses.replace(outcome, save_error=merged_save_error(outcome.save_error, run_dir, {name: why}))
