"""A recording of every run and a live view of the cell, with Rerun (the optional ``[viewer]`` extra).

- :class:`RunRecording` (:mod:`.live`): one more observer of the robot client and the vision communicator; writes
  ``run.rrd`` into the run folder and streams to a live viewer; the hooks only queue, a worker thread logs.
- :class:`ViewerServer` (:mod:`.viewer`): Rerun's web viewer and gRPC proxy in a ``rerun`` child process, bound to
  127.0.0.1 by default, analytics off.
- :func:`rrd_from_run` (:mod:`.from_csv`): the same ``run.rrd`` rebuilt from an older run folder's CSV logs.
- :class:`~aioadept.record.rrd.CellLogger` (:mod:`.rrd`): the entity layout both share (see its module docstring
  and ``docs/record.md``).

Nothing here imports Rerun at import time: without the extra, :func:`require_rerun` raises
:class:`ViewerUnavailable` whose message is the one line that says how to install it.
"""

from __future__ import annotations

from typing import Any

from aioadept.errors import ViewerUnavailable

__all__ = [
    "VIEWER_INSTALL_HINT", "RunRecording", "ViewerServer", "ViewerUnavailable", "rerun_available", "require_rerun",
    "rrd_from_run",
]

VIEWER_INSTALL_HINT = ("the live viewer needs the optional Rerun package: pip install 'aioadept[viewer]' "
                       "(or: pip install rerun-sdk==0.41.0)")


def rerun_available() -> bool:
    """True when ``rerun-sdk`` imports."""
    try:
        import rerun  # noqa: F401
    except ImportError:
        return False
    return True


def require_rerun() -> None:
    """Raise :class:`ViewerUnavailable` (with :data:`VIEWER_INSTALL_HINT`) unless ``rerun-sdk`` imports."""
    if not rerun_available():
        raise ViewerUnavailable(VIEWER_INSTALL_HINT)


def __getattr__(name: str) -> Any:
    # Lazy: `import aioadept.record` must work (and stay fast) without Rerun installed.
    if name == "RunRecording":
        from aioadept.record.live import RunRecording

        return RunRecording
    if name == "ViewerServer":
        from aioadept.record.viewer import ViewerServer

        return ViewerServer
    if name == "rrd_from_run":
        from aioadept.record.from_csv import rrd_from_run

        return rrd_from_run
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
