"""How an analysis reaches its folder: all of it or none of it, and what the disk could not take, named.

:func:`aioadept.analysis.report.analyze_runs` writes every output into a :func:`staging` folder beside the
destination, then :func:`publish` replaces the previous analysis as a whole; outputs that could not be written are
reported with :class:`AnalysisSaveError` (docs/analysis.md).
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path


__all__ = ["publish", "staging"]


@contextlib.contextmanager
def staging(out: Path) -> Iterator[Path]:
    """A fresh folder ``out/.analysis.<pid>.tmp`` for the outputs, removed on the way out whatever happens (an
    interrupted analysis leaves nothing behind)."""
    stage = out / f".analysis.{os.getpid()}.tmp"
    try:
        shutil.rmtree(stage, ignore_errors=True)
        stage.mkdir()
        yield stage
    finally:
        _remove_whole(stage)


def _remove_whole(stage: Path) -> None:
    """Remove ``stage`` even when Ctrl-C (KeyboardInterrupt, raised wherever the signal finds the program) lands in
    the middle of it, then raise that interrupt: a half-removed staging folder was once left behind so."""
    interrupted = False
    while True:
        try:
            shutil.rmtree(stage, ignore_errors=True)
            break
        except KeyboardInterrupt:
            interrupted = True
    if interrupted:
        raise KeyboardInterrupt


def publish(stage: Path, out: Path, staged: Mapping[str, Path], known: Iterable[str], *, last: str) -> None:
    """Replace the analysis in ``out`` with the ``staged`` files: ``last`` (the summary) is removed first, every
    ``known`` output not staged again is removed, then the staged files are renamed into place, ``last`` last. So no
    summary ever sits beside figures it did not make, and an interruption leaves at worst no summary."""
    names = {p.name for p in staged.values()}
    with contextlib.suppress(FileNotFoundError):
        os.unlink(out / last)
    for name in known:
        if name not in names:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(out / name)
    for path in sorted(staged.values(), key=lambda p: p.name == last):
        os.replace(path, out / path.name)
