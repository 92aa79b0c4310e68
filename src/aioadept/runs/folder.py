"""A run folder's files, written whole or named as not written: the focus result first, the recorder's tables, and
the merged list of what could not be written (``run.json``'s ``not_written``, the one stderr line)."""

from __future__ import annotations

import asyncio
import contextlib
import json
from pathlib import Path
from typing import Any


def merged_save_error(err: OSError | None, run_dir: Path, not_written: dict[str, str]) -> OSError:
    """``err`` (a run's ``save_error``, or None) with more files not written (name -> reason) added."""
    from aioadept.errors import RunSaveError

    more = RunSaveError(run_dir, (), not_written)
    if err is None:
        return more
    return err.merged(more) if isinstance(err, RunSaveError) else err


def run_error(exc: BaseException) -> str:
    """What ``run.json``'s ``error`` says of the exception that ended a run: the cause a cancellation carries (a
    node that died: :func:`aioadept.apps.processes.run_watched`), ``interrupted`` for Ctrl-C or a cancellation
    without one, else the exception's type and text."""
    if isinstance(exc, asyncio.CancelledError) and exc.args and isinstance(exc.args[0], str) and exc.args[0]:
        return exc.args[0]
    if isinstance(exc, (asyncio.CancelledError, KeyboardInterrupt)):
        return "interrupted"
    return f"{type(exc).__name__}: {exc}"


async def abandon_run(run_dir: Path, rrd: Any, state_tap: Any) -> None:
    """A run whose robot connection never succeeded: close its recording and state tap (either may be None), each
    shielded from the cancellation that may be ending the run, and :func:`discard_run_dir`."""
    if rrd is not None:
        await asyncio.shield(rrd.aclose())
    if state_tap is not None:
        await asyncio.shield(state_tap.stop())
    discard_run_dir(run_dir)


def discard_run_dir(run_dir: Path) -> None:
    """Remove a run folder whose robot connection never succeeded: its ``run.rrd`` (opened before connecting)
    and the folder, unless something else is in it (the logs of nodes a demo started: kept, they say why)."""
    with contextlib.suppress(OSError):
        (run_dir / "run.rrd").unlink(missing_ok=True)
    for d in (run_dir / "frames", run_dir / "logs", run_dir):
        with contextlib.suppress(OSError):
            d.rmdir()  # only when empty


def save_run(recorder: Any, run_dir: Path, meta: dict[str, Any]) -> OSError | None:
    """Write ``focus.json`` (the result, first: it matters most) and the recorder's tables; never raises OSError.

    Returns a :class:`~aioadept.errors.RunSaveError` naming every file not written, or None.
    """
    from aioadept.runs.capture import write_atomic
    from aioadept.errors import RunSaveError

    err: RunSaveError | None = None
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        write_atomic(run_dir / "focus.json", json.dumps(meta["result"] or {"error": meta["error"]}, indent=2))
        written: tuple[str, ...] = ("focus.json",)
    except OSError as exc:
        err = RunSaveError(run_dir, (), {"focus.json": exc.strerror or str(exc)})
        written = ()
    try:
        recorder.save(run_dir, metadata=meta)
    except RunSaveError as exc:
        err = exc if err is None else err.merged(exc)
    except OSError as exc:  # not expected from Recorder.save, but a result must never be lost to it
        more = RunSaveError(run_dir, (), {"run tables": exc.strerror or str(exc)})
        err = more if err is None else err.merged(more)
    if err is not None and written:
        err = RunSaveError(run_dir, (*written, *err.written), err.not_written)
    return err
