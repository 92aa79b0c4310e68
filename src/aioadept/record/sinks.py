"""Closing a Rerun recording without ever hanging the caller.

Rerun's ``flush`` and ``disconnect`` wait without bound once a file writer has died (EFBIG, ENOSPC): a full disk
must not hang a robot run or ``aioadept analyze``. Both recording paths (:mod:`aioadept.record.live`,
:mod:`aioadept.record.from_csv`) close through :func:`close_bounded`, then check the file with
:func:`rrd_incomplete` before renaming it into place: the file sink reports a failed write only in its own log.
"""

from __future__ import annotations

import contextlib
import os
import threading
from typing import Any


def close_bounded(rec: Any, timeout_s: float) -> list[str]:
    """Flush and disconnect ``rec`` (a ``rerun.RecordingStream``) in a daemon thread, giving up after about
    ``timeout_s``; returns the problems met (empty: everything written). When it gives up, Rerun's exit hook is
    unregistered too, since it would wait on the same dead writer."""
    done = threading.Event()
    errors: list[str] = []

    def finish() -> None:
        try:
            rec.flush(timeout_sec=timeout_s)
        except Exception as exc:  # noqa: BLE001 - reported, never raised: the caller decides
            errors.append(f"{type(exc).__name__}: {exc}")
        try:
            rec.disconnect()
        except Exception as exc:  # noqa: BLE001
            errors.append(f"{type(exc).__name__}: {exc}")
        done.set()

    threading.Thread(target=finish, name="rerun close", daemon=True).start()
    if not done.wait(timeout_s + 1.0):
        errors.append(f"the recording's writer did not finish within {timeout_s:g} s")
        with contextlib.suppress(Exception):
            import rerun as rr

            rr.unregister_shutdown()
    return errors


def rrd_incomplete(path: str | os.PathLike[str]) -> str | None:
    """Why the recording file at ``path`` is not complete (missing, cut short), or None when Rerun's reader finds
    its footer. Reads the footer only (~1 ms), not the file."""
    import warnings

    import rerun as rr

    if not os.path.exists(path):
        return "not written"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            rr.chunk.RrdReader(os.fspath(path))
        except Exception as exc:  # noqa: BLE001 - Rerun raises RuntimeError for a file it cannot read
            return f"cut short ({exc})"
    if any("footer" in str(w.message) for w in caught):
        return "cut short (no footer: the disk full?)"
    return None
