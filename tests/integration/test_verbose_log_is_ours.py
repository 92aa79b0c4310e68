"""``-v`` shows this project's log, not third-party libraries' DEBUG/INFO (matplotlib's font search printed ~300
lines on a one-part ``aioadept pickplace -v``): the one logging setup every command uses
(:func:`aioadept.cli.options.setup_logging`) drops other loggers' records below WARNING."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


@pytest.mark.timeout(90)
def test_pickplace_verbose_prints_no_matplotlib_font_debug(tmp_path):
    res = subprocess.run([sys.executable, "-m", "aioadept", "pickplace", "--parts", "1", "-v", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=80, env={**os.environ, "COLUMNS": "200"})
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-2000:]
    assert "findfont" not in out and "FontEntry" not in out, out[:2000]
    assert len(out.splitlines()) < 30, out[:3000]


@pytest.mark.timeout(30)
def test_the_shared_setup_keeps_our_debug_and_others_warnings_only():
    code = ("import logging; from aioadept.cli.options import setup_logging; setup_logging('debug'); "
            "logging.getLogger('aioadept.demo').debug('ours-debug'); logging.getLogger('matplotlib.font_manager')"
            ".debug('theirs-debug'); logging.getLogger('asyncio').info('theirs-info'); "
            "logging.getLogger('zenoh').warning('theirs-warning')")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=20)
    assert res.returncode == 0, res.stderr
    assert "ours-debug" in res.stderr and "theirs-warning" in res.stderr
    assert "theirs-debug" not in res.stderr and "theirs-info" not in res.stderr
