"""``aioadept demo --config FILE`` with a cell of several robots (``[[robots]]``/``[[cameras]]``): every robot
calibrates its own camera at the same time, coordinated by this process (:mod:`aioadept.apps.multicell`).

It prints one line per robot (the plane found against the one its camera was given, steps, search time, run
folder), analyses each robot's sub-folder as ``aioadept demo`` does its run folder, and exits 0 when every robot
found its plane and every file was written, 1 when a robot failed (the others still ran to their end), 4 when a
result was found but not fully saved, 130 after Ctrl-C with every robot stopped.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
from collections.abc import Callable
from typing import Any

log = logging.getLogger("aioadept.demo")

PROG = "aioadept demo"


def multi_config(args: argparse.Namespace, data: dict[str, Any], options: Callable[..., Any]) -> Any:
    """The file's cell with the command line's ``options`` (``aioadept demo``'s) applied to every robot
    (ValueError naming the mistake)."""
    from aioadept.cell.multi import multi_from_dict

    multi = multi_from_dict(data, source=str(args.config))
    for m in multi.members:
        m.cfg = options(m.cfg, args, from_file=True)
    return multi


def main_multi(args: argparse.Namespace, data: dict[str, Any], options: Callable[..., Any]) -> int:
    """``options(cfg, args, from_file=True)``: the demo's options applied to one robot's cell."""
    from aioadept.apps.interrupt import run_interruptible
    from aioadept.apps.multicell import new_multi_run_dir, run_multi
    from aioadept.cell.schema import report
    from aioadept.record.hook import keep_frames

    if getattr(args, "view", False):
        print(f"{PROG}: --view: one live view per robot is not offered for a cell of several robots; each robot's "
              f"run.rrd is written in its sub-folder (docs/record.md)", file=sys.stderr)
        return 2
    try:
        multi = multi_config(args, data, options)
    except (OSError, ValueError) as exc:
        return report(PROG, exc, verbose=args.verbose)
    try:
        run_dir = new_multi_run_dir(multi)
    except OSError as exc:
        print(f"{PROG}: cannot create a run folder in {multi.base.run.out_dir!r}: {exc}; nothing was started",
              file=sys.stderr)
        return 2
    log.info("run folder %s (one sub-folder per robot)", run_dir)
    for m in multi.members:
        keep_frames(m.cfg, args, run_dir / m.robot / "frames")
    results: list[Any] = []

    async def main(intr: Any) -> int:
        results.extend(await run_multi(multi, run_dir, interrupter=intr))
        return 0

    try:
        code = run_interruptible(main, prog=PROG)
    except Exception as exc:  # one line; each robot's logs are in its sub-folder
        print(" ".join(f"{PROG} failed: {type(exc).__name__}: {exc} (logs in {run_dir})".split()), file=sys.stderr)
        return 1
    if code or not results:
        return code or 1
    return _report(multi, results, run_dir)


def _report(multi: Any, results: list[Any], run_dir: Any) -> int:
    from aioadept.apps.interrupt import EXIT_INTERRUPTED, interrupt_handled
    from aioadept.cli.report import EXIT_NOT_SAVED, report_saving, stop_signals_interrupt

    cfgs = {m.robot: m.cfg for m in multi.members}
    failed = 0
    not_saved = 0
    try:
        with stop_signals_interrupt():
            for r in results:
                res = r.outcome.result if r.outcome is not None else None
                if res is None:
                    failed += 1
                    why = r.error or (r.outcome.error if r.outcome is not None else "no result")
                    print(f"{r.robot} ({r.camera}): FAILED: {why} (logs in {r.run_dir / 'logs'})")
                    continue
                given = cfgs[r.robot].vision.focus_offset_mm
                search = f", search {res.search_s:.2f} s" if res.search_s is not None else ""
                print(f"{r.robot} ({r.camera}): focal plane {res.peak_offset_mm:.2f} mm along tool z (camera's "
                      f"{given:g} mm), {res.steps} steps{search}; run folder {r.run_dir}")
                if report_saving(r.outcome, analyze=cfgs[r.robot].run.analyze, prog=f"{PROG} {r.robot}"):
                    not_saved += 1
    except KeyboardInterrupt:
        interrupt_handled()
        with contextlib.suppress(OSError, ValueError):
            print(f"{PROG}: interrupted after the run: the runs are kept in {run_dir}", file=sys.stderr, flush=True)
        return EXIT_INTERRUPTED
    print(f"{len(results) - failed} of {len(results)} robots found their focal plane; summary in "
          f"{run_dir / 'multi.json'}")
    if failed:
        print(f"{PROG}: {failed} of {len(results)} robots failed (see above)", file=sys.stderr)
        return 1
    return EXIT_NOT_SAVED if not_saved else 0
