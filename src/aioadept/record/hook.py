"""How the applications use the recording: the ``--view`` options, the viewer's life, one recording per run.

``aioadept demo``, ``focus`` and ``experiment`` call :func:`add_view_options` on their parser, :func:`start_viewer`
before the first run (it prints the URL, or the one line that says how to install the extra), and
:func:`open_run_recording` in :func:`aioadept.apps.cell.run_focus_once` for every run. The choice of what is
recorded lives here, so the applications stay a few lines longer than before.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from collections.abc import Callable
from typing import Any

from aioadept.errors import ViewerUnavailable
from aioadept.record import VIEWER_INSTALL_HINT, rerun_available

__all__ = ["add_view_options", "frames_dir_of", "keep_frames", "open_run_recording", "run_with_viewer", "start_viewer",
           "mcap_wanted", "open_state_tap", "wait_for_viewer", "write_run_mcap_of"]

log = logging.getLogger(__name__)


def add_view_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--view", action="store_true",
                   help="serve Rerun's web viewer and stream the run live (needs the [viewer] extra); prints the URL")
    p.add_argument("--view-host", dest="view_host", default="127.0.0.1", metavar="ADDR",
                   help="address the viewer binds (default 127.0.0.1; 0.0.0.0 opens it to the network, "
                        "see docs/security.md)")
    p.add_argument("--no-record", dest="no_record", action="store_true",
                   help="do not write run.rrd and run.mcap into the run folder")


def refuse_view_without_rerun(args: argparse.Namespace, prog: str) -> bool:
    """True (after one line on stderr) when ``--view`` was asked for and the ``[viewer]`` extra is missing. Checked
    before a run folder is made or anything is started, so the mistake leaves nothing behind."""
    if getattr(args, "view", False) and not rerun_available():
        print(f"{prog}: --view: {VIEWER_INSTALL_HINT}", file=sys.stderr)
        return True
    return False


def start_viewer(args: argparse.Namespace, prog: str, *, log_path: Path | None = None) -> Any:
    """The :class:`~aioadept.record.ViewerServer` asked for by ``--view`` (None without it), URL printed.

    Raises :class:`ViewerUnavailable` with one line (how to install the extra, or why the viewer did not start).
    """
    if not getattr(args, "view", False):
        return None
    if not rerun_available():
        raise ViewerUnavailable(VIEWER_INSTALL_HINT)
    from aioadept.record.viewer import ViewerServer

    viewer = ViewerServer(args.view_host, log_path=log_path).start()
    print(f"{prog}: live viewer at {viewer.url}", file=sys.stderr, flush=True)
    return viewer


def wait_for_viewer(viewer: Any, prog: str) -> None:
    """After the run: keep the viewer up until Enter or Ctrl-C when a person is at the terminal."""
    if viewer is None or not sys.stdin.isatty():
        return
    print(f"{prog}: the viewer stays at {viewer.url}; press Enter or Ctrl-C to close it", file=sys.stderr,
          flush=True)
    try:
        sys.stdin.readline()
    except KeyboardInterrupt:
        pass


def keep_frames(cfg: Any, args: argparse.Namespace, folder: Path) -> None:
    """Have the vision node started for ``cfg`` (a CellConfig) save the frames it serves into ``folder`` when they
    will be recorded (``run.rrd``, ``run.mcap``) or shown (``--view``)."""
    from aioadept.record.mcapfile import mcap_available

    if (cfg.run.record and (rerun_available() or mcap_available())) or getattr(args, "view", False):
        cfg.vision.save_frames = str(folder)


def frames_dir_of(cfg: Any) -> Path | None:
    """The folder the vision node of ``cfg`` saves its frames into: the cell's ``save_frames``, else a
    ``--save-frames`` among its ``vision_args`` (None if neither)."""
    if getattr(cfg.vision, "save_frames", None):
        return Path(cfg.vision.save_frames)
    args = list(cfg.vision.vision_args)
    for i, a in enumerate(args):
        if a == "--save-frames" and i + 1 < len(args):
            return Path(args[i + 1])
        if a.startswith("--save-frames="):
            return Path(a.split("=", 1)[1])
    return None


def run_with_viewer(args: argparse.Namespace, prog: str, cfg: Any, log_path: Path, run: Callable[[], int]) -> int:
    """``run()`` with the viewer ``--view`` asks for (its URL in ``cfg.run.view_url``), kept up afterwards while a
    person is at the terminal, then closed. Exit 2 with one line when the viewer cannot start."""
    try:
        viewer = start_viewer(args, prog, log_path=log_path)
    except ViewerUnavailable as exc:
        print(f"{prog}: --view: {exc}", file=sys.stderr)
        return 2
    if viewer is not None:
        cfg.run.view_url = viewer.grpc_url
    try:
        return run()
    finally:
        if viewer is not None:
            wait_for_viewer(viewer, prog)
            viewer.close()


def open_run_recording(cfg: Any, run_dir: Path, recorder: Any) -> Any:
    """A started :class:`~aioadept.record.RunRecording` for one run of ``cfg`` (a CellConfig), or None.

    None when ``cfg.run.record`` is off and no viewer is open, or when Rerun is not installed (then the run goes on
    without ``run.rrd``: recording is a convenience, never a reason to fail a run). Call it inside the event loop.
    """
    view_url = getattr(cfg.run, "view_url", "") or None
    if not getattr(cfg.run, "record", True) and view_url is None:
        return None
    if not rerun_available():
        log.debug("rerun-sdk not installed: no run.rrd (%s)", VIEWER_INSTALL_HINT)
        return None
    from aioadept.bus.endpoints import is_none
    from aioadept.record.live import RunRecording
    from aioadept.robots import model as robot_model

    try:
        rec = RunRecording(run_dir / "run.rrd" if getattr(cfg.run, "record", True) else None,
                           viewer_url=view_url,
                           state_endpoint=None if is_none(cfg.robot.state_endpoint) else cfg.robot.state_endpoint,
                           frames_dir=frames_dir_of(cfg), clock_ref=recorder,
                           name=run_dir.name, short_switch_interval=True, world=getattr(cfg, "world", None),
                           arm=robot_model(cfg.robot.model))
    except Exception as exc:  # noqa: BLE001 - see the docstring: never fail a run for its recording
        log.warning("no run.rrd for this run: %s", exc)
        return None
    return rec.start()


def mcap_wanted(cfg: Any) -> bool:
    """True when runs of ``cfg`` (a CellConfig) get a ``run.mcap``: ``cfg.run.record`` on and the ``[mcap]`` extra
    installed (without it the run goes on without the file: as with run.rrd, a convenience never fails a run)."""
    from aioadept.record.mcapfile import MCAP_INSTALL_HINT, mcap_available

    if not getattr(cfg.run, "record", True):
        return False
    if not mcap_available():
        log.debug("no run.mcap (%s)", MCAP_INSTALL_HINT)
        return False
    return True


def open_state_tap(cfg: Any) -> Any:
    """A started :class:`~aioadept.record.mcapfile.StateTap` on the robot's state stream for ``run.mcap``, or None
    (no run.mcap, or no state endpoint). Call it inside the event loop."""
    from aioadept.bus.endpoints import is_none

    if not mcap_wanted(cfg) or is_none(cfg.robot.state_endpoint):
        return None
    from aioadept.record.mcapfile import StateTap

    return StateTap(cfg.robot.state_endpoint).start()


def write_run_mcap_of(cfg: Any, run_dir: Path, recorder: Any, meta: dict[str, Any],
                      state: list[bytes] | None = None) -> str | None:
    """Write ``run.mcap`` of the run ``recorder`` (a :class:`aioadept.runs.capture.Recorder`) recorded into ``run_dir``,
    with the ``state`` payloads an :func:`open_state_tap` kept; None when written or not wanted
    (:func:`mcap_wanted`), else why it was not written. Blocking: call it in a thread."""
    if not mcap_wanted(cfg):
        return None
    from aioadept.record.mcapfile import write_run_mcap

    return write_run_mcap(recorder.snapshot(metadata=meta), run_dir / "run.mcap", frames_dir=frames_dir_of(cfg),
                          state=state)


class MarkTee:
    """Sends the application's marks to the timing recorder and to the Rerun recording."""

    def __init__(self, *targets: Any) -> None:
        self.targets = [t for t in targets if t is not None]

    def mark(self, name: str, value: Any = None, *, t_s: float | None = None) -> None:
        from aioadept.record.live import _loop_clock

        t_s = _loop_clock() if t_s is None else t_s  # one instant for both logs
        for t in self.targets:
            t.mark(name, value, t_s=t_s)
