"""``run.json`` records the cell this run used: the vision node a cell starts follows the robot's state stream
(``robot.state_endpoint``, on its command line), so the ``[vision] state_endpoint`` nobody used (the default
tcp://127.0.0.1:5560) is not recorded beside it. A real ``aioadept pickplace`` run; its vision node's log says
which stream it followed."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest


@pytest.mark.timeout(90)
def test_run_json_records_the_state_stream_the_vision_node_followed_and_no_other(tmp_path):
    res = subprocess.run([sys.executable, "-m", "aioadept", "pickplace", "--parts", "1", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=80)
    assert res.returncode == 0, res.stderr[-2000:]
    (run_dir,) = [p.parent for p in tmp_path.glob("*/run.json")]
    cell = json.loads((run_dir / "run.json").read_text(encoding="utf-8"))["parameters"]["cell"]
    assert "state_endpoint" not in cell["vision"], cell["vision"]
    used = cell["robot"]["state_endpoint"]
    assert f"following robot state on {used}" in (run_dir / "logs" / "vision.log").read_text(encoding="utf-8")
