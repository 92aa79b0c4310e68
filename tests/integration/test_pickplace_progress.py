"""``aioadept pickplace`` shows where a long run is: a line per placed part as the focus app's per step
(a real run: the sim and the vision node as processes)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


@pytest.mark.timeout(90)
def test_each_placed_part_prints_a_progress_line(tmp_path):
    res = subprocess.run([sys.executable, "-m", "aioadept", "pickplace", "--parts", "2", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=80, env={**os.environ, "COLUMNS": "200"})
    assert res.returncode == 0, res.stderr[-2000:]
    progress = [ln for ln in (res.stdout + res.stderr).splitlines() if "placed: slot" in ln]  # the log's stream
    assert len(progress) == 2, res.stdout + res.stderr
    assert "part 1 of 2 placed: slot 0" in progress[0] and "part 2 of 2 placed: slot 1" in progress[1]
