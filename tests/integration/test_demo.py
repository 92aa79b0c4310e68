"""``aioadept demo`` and ``aioadept focus`` as a user runs them: real processes, real sockets, files on disk."""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from aioadept.ports import free_port

AIOADEPT = [sys.executable, "-m", "aioadept"]


def _live_cmdlines() -> set[str]:
    out = set()
    for pid in os.listdir("/proc"):
        if pid.isdigit():
            try:
                raw = Path(f"/proc/{pid}/cmdline").read_bytes()
            except OSError:
                continue
            if raw:
                out.add(" ".join(a.decode(errors="replace") for a in raw.rstrip(b"\0").split(b"\0")))
    return out


@pytest.mark.timeout(120)
@pytest.mark.parametrize("transport", ["zeromq", "zenoh"])
def test_demo_fast_finds_the_focus_plane_writes_the_run_folder_and_leaves_no_process(tmp_path, transport):
    if transport == "zenoh":
        pytest.importorskip("zenoh", reason="the [zenoh] extra (eclipse-zenoh) is not installed")
    focus_offset_mm, delta_z_mm = 16.0, 2.0
    proc = subprocess.run(
        [*AIOADEPT, "demo", "--fast", "--out", str(tmp_path), "--focus-offset-mm", str(focus_offset_mm),
         "--delta-z", str(delta_z_mm), "--transport", transport],
        capture_output=True, text=True, timeout=110)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    focus = json.loads((run_dir / "focus.json").read_text())
    assert abs(focus["peak_offset_mm"] - focus_offset_mm) <= delta_z_mm
    assert focus["sharpness"][focus["peak_index"]] == max(focus["sharpness"])
    assert "inspection-start pose" in proc.stdout

    for name in ("robot.csv", "vision.csv", "run.json", "summary.json", "fig09_sharpness.png", "fig10_gantt.png",
                 "fig11_tau_r.png", "fig12_switching_robot_vision.png", "fig13_switching_sends.png"):
        assert (run_dir / name).stat().st_size > 0, name
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["n_runs"] == 1
    assert summary["n_complete"] == len(focus["sharpness"]) - 1  # one robot increment per step but the last
    assert {"tau_r_ms", "tau_r_to_v_ms", "tau_v_to_r_ms", "tau_ss_to_mrt_ms", "tau_mrt_to_b_ms"} <= set(summary["quantities"])

    # Every node the demo started is gone: their exact command lines (first line of each log) are not running.
    started = [(run_dir / "logs" / f).read_text().splitlines()[0].removeprefix("$ ")
               for f in ("sim.log", "vision.log")]
    live = _live_cmdlines()
    for cmd in started:
        assert " ".join(shlex.split(cmd)) not in live, f"still running: {cmd}"
    # The run went over the transport asked for: the nodes were started on it (and the peak above shows the virtual
    # camera followed the robot state over it).
    for cmd in started:
        assert ("--transport zenoh" in cmd) == (transport == "zenoh"), cmd
        assert ("zenoh:aioadept/demo/" in cmd) == (transport == "zenoh"), cmd


@pytest.mark.timeout(30)
def test_focus_against_an_absent_robot_server_fails_with_a_clear_connection_error(tmp_path):
    port = free_port()
    proc = subprocess.run(
        [*AIOADEPT, "focus", "--robot", f"127.0.0.1:{port}", "--out", str(tmp_path), "--no-analyze"],
        capture_output=True, text=True, timeout=25)
    assert proc.returncode == 1
    # One line on stderr naming the address, and no run folder: the connection never succeeded.
    (line,) = proc.stderr.splitlines()
    assert line.startswith(f"aioadept focus failed: connect to 127.0.0.1:{port}: "), line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.timeout(60)
def test_focus_with_an_absent_vision_node_fails_after_the_timeout_with_the_robot_retracted(tmp_path):
    sim = subprocess.Popen([*AIOADEPT, "sim", "--port", "0", "--state-endpoint", "none", "--time-scale", "20"],
                           stdout=subprocess.PIPE, text=True)
    try:
        ready = sim.stdout.readline()
        assert ready.startswith("READY"), ready
        port = dict(f.split("=", 1) for f in ready.split()[1:])["port"]
        req, resp = free_port(), free_port()
        proc = subprocess.run(
            [*AIOADEPT, "focus", "--robot", f"127.0.0.1:{port}", "--out", str(tmp_path), "--no-analyze",
             "--request-endpoint", f"tcp://127.0.0.1:{req}", "--response-endpoint", f"tcp://127.0.0.1:{resp}",
             "--vision-timeout", "1.0"],
            capture_output=True, text=True, timeout=50)
    finally:
        sim.terminate()
        sim.wait(10)
    assert proc.returncode == 1
    text = " ".join((proc.stdout + proc.stderr).split())
    assert "no answer from the vision node" in text
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["parameters"]["error"].startswith("FocusError: step 0: no answer from the vision node")


@pytest.mark.timeout(150)
def test_experiment_runs_the_grid_with_the_nodes_started_once_and_pools_the_analysis(tmp_path):
    proc = subprocess.run(
        [*AIOADEPT, "experiment", "--speeds", "50,100", "--delta-z", "2.5", "--runs", "1", "--time-scale", "20",
         "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=140)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    runs = sorted(p for p in tmp_path.iterdir() if (p / "run.json").exists())
    assert [json.loads((r / "run.json").read_text())["parameters"]["approach_speed"] for r in runs] == [50, 100]
    summary = json.loads((tmp_path / "analysis" / "summary.json").read_text())
    assert summary["n_runs"] == 2
    assert (tmp_path / "analysis" / "fig11_tau_r.png").stat().st_size > 0
    # One sim and one vision node served both runs.
    assert sorted(p.name for p in (tmp_path / "logs").iterdir()) == ["sim.log", "vision.log"]
