"""A node that dies mid-run is named in the run folder, not taken for Ctrl-C.

``aioadept pickplace`` and ``aioadept demo`` run as a user runs them (real processes, real sockets); once the
vision node they started has answered a request it is SIGKILLed. The app ends with exit code 1, stops the other
node and prints one line naming the dead node; the run folder's ``error`` (``summary.json``, ``run.json``, and
the demo's ``focus.json``) is the same words, never ``interrupted``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
AIOADEPT = [sys.executable, "-m", "aioadept"]
CAUSE = "NodeError: vision exited unexpectedly with code -9"


def _nodes_of(pid: int) -> dict[str, int]:
    """The child node processes of ``pid`` by node name (``python -m aioadept <node> ...``)."""
    out = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        for child in (task / "children").read_text().split():
            try:
                argv = Path(f"/proc/{child}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if argv[1:3] == [b"-m", b"aioadept"]:
                out[argv[3].decode()] = int(child)
    return out


def _kill_vision_after_its_first_request(proc: subprocess.Popen, runs: Path) -> dict[str, int]:
    """Wait until the vision node has logged a request it served, SIGKILL it; the app's nodes by name."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        logs = list(runs.glob("*/logs/vision.log"))
        if logs and "t_request=" in logs[0].read_text():
            nodes = _nodes_of(proc.pid)
            os.kill(nodes["vision"], signal.SIGKILL)
            return nodes
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError("the vision node served no request within 60 s")


def _run_and_kill(argv: list[str], runs: Path, cwd: Path) -> tuple[int, list[str], Path, dict[str, int]]:
    proc = subprocess.Popen([*AIOADEPT, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd)
    try:
        nodes = _kill_vision_after_its_first_request(proc, runs)
        _out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    return proc.returncode, err.strip().splitlines(), run_dir, nodes


def _gone(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1].startswith("Z")
    except OSError:
        return True


@pytest.mark.timeout(120)
def test_pickplace_names_the_vision_node_that_died_in_its_run_folder(tmp_path):
    runs = tmp_path / "runs"
    code, lines, run_dir, nodes = _run_and_kill(
        ["pickplace", "--config", str(ROOT / "examples" / "pickplace-cell.toml"), "--out", str(runs),
         "--speed", "20"], runs, tmp_path)
    assert code == 1 and len(lines) == 1 and CAUSE in lines[0], lines
    assert _gone(nodes["sim"]), "the sim node was left running"
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["error"] == CAUSE, summary["error"]
    assert summary["parts_placed"] < 6
    assert json.loads((run_dir / "run.json").read_text())["parameters"]["error"] == CAUSE


@pytest.mark.timeout(120)
def test_demo_names_the_vision_node_that_died_in_its_run_folder(tmp_path):
    runs = tmp_path / "runs"
    code, lines, run_dir, nodes = _run_and_kill(["demo", "--out", str(runs), "--no-analyze"], runs, tmp_path)
    assert code == 1 and len(lines) == 1 and CAUSE in lines[0], lines
    assert _gone(nodes["sim"]), "the sim node was left running"
    assert json.loads((run_dir / "run.json").read_text())["parameters"]["error"] == CAUSE
    assert json.loads((run_dir / "focus.json").read_text()) == {"error": CAUSE}
