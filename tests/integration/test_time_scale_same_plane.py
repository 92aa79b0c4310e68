"""``--time-scale 10`` finds the focus plane where real time does, under every default:
``aioadept sim``, ``aioadept vision`` and ``aioadept focus`` as a user starts them, only addresses configured.

Fast motion must not change the answer: the software-triggered camera exposes after each request, and the virtual
camera holds an at-rest pose only from a sample that says the robot has stopped (the sim publishes one when a
motion ends), so no frame shows the robot before it arrived at any time scale.
"""

from __future__ import annotations

import asyncio
import json
import sys
from pathlib import Path

import pytest

from aioadept.testing.nodes import running_node

AIOADEPT = [sys.executable, "-m", "aioadept"]


async def _calibrate(tmp_path: Path, time_scale: str) -> dict:
    logs = tmp_path / f"logs-{time_scale}"
    logs.mkdir()
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0", "--time-scale",
                            time_scale, log_path=logs / "sim.log") as sim, \
            running_node("vision", "--state-endpoint", sim.ready["state"], "--request-endpoint",
                         "tcp://127.0.0.1:0", "--response-endpoint", "tcp://127.0.0.1:0",
                         log_path=logs / "vision.log") as vision:
        out = tmp_path / f"runs-{time_scale}"
        proc = await asyncio.create_subprocess_exec(
            *AIOADEPT, "focus", "--robot", f"127.0.0.1:{sim.ready['port']}", "--request-endpoint",
            vision.ready["request"], "--response-endpoint", vision.ready["response"], "--out", str(out),
            "--no-analyze", stdin=asyncio.subprocess.DEVNULL, stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE)
        async with asyncio.timeout(120):
            out_b, err_b = await proc.communicate()
    assert proc.returncode == 0, out_b.decode(errors="replace") + err_b.decode(errors="replace")
    (run_dir,) = out.iterdir()
    return json.loads((run_dir / "focus.json").read_text())


@pytest.mark.timeout(300)
async def test_time_scale_10_finds_the_focus_plane_where_real_time_does(tmp_path):
    real = await _calibrate(tmp_path, "1")
    fast = await _calibrate(tmp_path, "10")
    assert real["peak_index"] == fast["peak_index"], (real["sharpness"], fast["sharpness"])
    assert real["peak_offset_mm"] == pytest.approx(fast["peak_offset_mm"])
    assert real["peak_offset_mm"] == pytest.approx(20.0, abs=2.0)  # the default cell's focal plane
