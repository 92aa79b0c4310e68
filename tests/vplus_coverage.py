"""pytest plugin: the V+ line coverage of ``vplus/*.V2`` by the emulated servers the tests start, printed at the end.

Every ``aioadept sim --vplus`` a test starts inherits ``AIOADEPT_VPLUS_LINES`` (a temporary folder) and writes the
lines it ran there when it ends (:mod:`aioadept.vplus.linehits`); at the end of the run the folder's files are
merged and each ``vplus/*.V2`` file is printed with its statements, misses, percentage and missed lines. Nothing is
printed when no emulated server ran. With ``AIOADEPT_VPLUS_LINES`` set by the caller, that folder is used and
kept, so several runs add up. Registered by tests/conftest.py; ``-p no:vplus_coverage`` turns it off.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest

from aioadept.vplus import linehits

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "vplus").glob("*.V2"))


def pytest_configure(config: pytest.Config) -> None:
    if hasattr(config, "workerinput"):
        return                          # a pytest-xdist worker: its servers write into the folder it inherited
    folder = os.environ.get(linehits.ENV)
    if folder:
        config.stash[_KEEP] = True      # the caller's folder: reported, and kept (several runs add up there)
    else:
        folder = os.environ[linehits.ENV] = tempfile.mkdtemp(prefix="vplus-lines-")
    config.stash[_FOLDER] = folder


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter, config: pytest.Config) -> None:
    folder = config.stash.get(_FOLDER, None)
    if folder is None:
        return
    hits = linehits.load(folder)
    if not any(os.path.abspath(f) in hits for f in SHIPPED):
        return
    terminalreporter.write_sep("-", "V+ line coverage of vplus/ (the lines the emulated servers ran)")
    terminalreporter.write_line(linehits.table(linehits.report(hits, SHIPPED), ROOT))


def pytest_unconfigure(config: pytest.Config) -> None:
    folder = config.stash.get(_FOLDER, None)
    if folder is not None and not config.stash.get(_KEEP, False):
        del os.environ[linehits.ENV]
        shutil.rmtree(folder, ignore_errors=True)


_FOLDER = pytest.StashKey[str]()
_KEEP = pytest.StashKey[bool]()
