"""The long fuzz run's script stays runnable: a short run of both phases (the live sim over real TCP) passes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[3] / "scripts" / "fuzz_protocol.py"


@pytest.mark.timeout(60)
def test_short_fuzz_run_reports_clean_figures(tmp_path):
    out = tmp_path / "report.json"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--n", "400", "--batch", "100", "--seed", "3",
                           "--json", str(out)], capture_output=True, text=True, timeout=55)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    report = json.loads(out.read_text())
    core, sim = report["core"], report["sim"]
    assert core["inputs"] == 400 and core["framed_items"] == core["acks"] > 0
    assert core["unexpected_exceptions"] == {} and core["malformed_without_error_ack"] == 0
    assert set(core["parse_exceptions_by_type"]) <= {"RemoteProtocolError"}
    assert core["malformed_items"] > 50  # the generator does produce garbage
    assert core["error_acks_that_moved_the_arm"] == 0
    assert sim["lines_sent"] == 400 and sim["framed_items"] == sim["acks"]
    assert sim["malformed_without_error_ack"] == 0 and sim["acks_with_wrong_id"] == 0
    assert sim["final_here"]["status"] == "done" and sim["sim_stderr_tracebacks"] == 0
