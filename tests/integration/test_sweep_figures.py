"""The figures of a sweep run draw the sweep's positions: a real ``aioadept focus --mode sweep``
against a real sim and vision node, then the analysis of its run folder, each figure caught as the analysis saves it.

Fig. 9 of the stepwise loop is sharpness per step; a sweep has no steps, and drawing its frames at 0, 1, 2 ... with
"delta z = 2 mm" put the maximum at "step 8" (16 mm) beside a fitted plane of 19.99 mm.
"""

from __future__ import annotations

import asyncio
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from aioadept.analysis import plots
from aioadept.analysis.report import FIGURES, analyze_runs
from aioadept.testing.nodes import running_node

AIOADEPT = [sys.executable, "-m", "aioadept"]
PLANE_MM = 19.99


async def sweep_run(tmp_path: Path) -> Path:
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0",
                            log_path=tmp_path / "sim.log") as sim, \
            running_node("vision", "--state-endpoint", sim.ready["state"], "--request-endpoint", "tcp://127.0.0.1:0",
                         "--response-endpoint", "tcp://127.0.0.1:0", "--focus-offset-mm", str(PLANE_MM),
                         log_path=tmp_path / "vision.log") as vision:
        cfg = tmp_path / "cell.toml"
        cfg.write_text(f"[robot]\nstate_endpoint = \"{sim.ready['state']}\"\n[focus]\nmode = \"sweep\"\n"
                       "[run]\nanalyze = false\nrecord = false\n")
        proc = await asyncio.create_subprocess_exec(
            *AIOADEPT, "focus", "--config", str(cfg), "--robot", f"127.0.0.1:{sim.ready['port']}",
            "--request-endpoint", vision.ready["request"], "--response-endpoint", vision.ready["response"],
            "--out", str(tmp_path / "runs"), stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
        _out, err = await asyncio.wait_for(proc.communicate(), 60)
    assert proc.returncode == 0, err.decode()
    (run_dir,) = (tmp_path / "runs").iterdir()
    return run_dir


@pytest.mark.timeout(90)
async def test_fig09_of_a_sweep_run_is_drawn_at_the_sweeps_positions(tmp_path, monkeypatch):
    run_dir = await sweep_run(tmp_path)
    result = json.loads((run_dir / "focus.json").read_text())
    assert result["mode"] == "sweep" and abs(result["peak_offset_mm"] - PLANE_MM) < 0.2

    saved: dict[str, object] = {}
    save = plots._save

    def spy(fig, path):  # noqa: ANN001, ANN202 - the figure as the analysis hands it over to be written
        saved[Path(path).name] = fig
        return save(fig, path)

    monkeypatch.setattr(plots, "_save", spy)
    analyze_runs([run_dir], tmp_path / "analysis")

    fig = saved[FIGURES["sharpness"]]
    (ax,) = fig.axes
    assert "mm" in ax.get_xlabel() and "step" not in ax.get_xlabel()
    # The frames at their positions along the sweep, every one of them.
    frames = sorted((f["offset_mm"], f["sharpness"]) for f in result["frames"])
    drawn = sorted((float(x), float(y)) for line in ax.get_lines() if line.get_marker() == "o"
                   for x, y in zip(line.get_xdata(), line.get_ydata(), strict=True))
    assert len(drawn) == len(frames) and np.allclose(drawn, frames)
    # The peak marker (the red vertical line) at the fitted plane, not at a step number.
    (marker,) = [line for line in ax.get_lines() if line.get_color() == "red"]
    xs = {float(x) for x in marker.get_xdata()}
    assert len(xs) == 1 and abs(xs.pop() - result["peak_offset_mm"]) < 0.01
    # No other figure of this run draws steps.
    for name, other in saved.items():
        for axis in other.axes:
            assert "step" not in axis.get_xlabel(), name
