"""``aioadept analyze runs/*`` beside the logs-only folder a failed demo leaves."""

from __future__ import annotations

import subprocess
import sys

import pytest

AIOADEPT = [sys.executable, "-m", "aioadept"]


@pytest.mark.timeout(180)
def test_analyze_skips_a_logs_only_folder_with_a_note_and_analyzes_the_rest(tmp_path):
    runs = tmp_path / "runs"
    demo = subprocess.run([*AIOADEPT, "demo", "--fast", "--no-analyze", "--no-record", "--out", str(runs)],
                          capture_output=True, text=True, timeout=150, cwd=tmp_path)
    assert demo.returncode == 0, demo.stdout + demo.stderr
    failed = runs / "20990101-000000-000-failed" / "logs"
    failed.mkdir(parents=True)
    (failed / "sim.log").write_text("$ aioadept sim\n")
    folders = sorted(str(p) for p in runs.iterdir())  # what the shell makes of runs/*
    assert len(folders) == 2

    proc = subprocess.run([*AIOADEPT, "analyze", "--no-rrd", *folders], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    notes = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert notes == [f"aioadept analyze: skipping {failed.parent}: no run.json here or below (e.g. a failed "
                     "run's logs)"]
    assert "Traceback" not in proc.stderr

    only_logs = subprocess.run([*AIOADEPT, "analyze", str(failed.parent)], capture_output=True, text=True,
                               timeout=60, cwd=tmp_path)
    assert only_logs.returncode == 2
    assert only_logs.stderr.splitlines()[-1] == "aioadept analyze: no run folder (run.json) in any of the paths given"


@pytest.mark.timeout(60)
def test_analyze_help_says_where_it_writes():
    proc = subprocess.run([*AIOADEPT, "analyze", "--help"], capture_output=True, text=True, timeout=60)
    assert "./analysis/" in " ".join(proc.stdout.split())
