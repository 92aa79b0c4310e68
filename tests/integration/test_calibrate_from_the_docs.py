"""docs/vision.md's "Try it on the simulated cell", run as written: the shell lines of its block, in a folder holding
a copy of the checkout's ``examples/``, with the ``aioadept`` of this interpreter. ``aioadept calibrate --config``
starts the sim and the vision node as ``aioadept demo`` does, the world camera draws the cell's tool marker at the
sim's tool pose, and the camera pose written into the cell file is the world camera's own. A ``--write`` path in a
folder that does not exist is refused before anything starts or moves."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from aioadept.geometry import pose_error
from aioadept.vision.calibration import CameraCalibration
from aioadept.cell.world import load_world

ROOT = Path(__file__).resolve().parents[2]


def documented_lines() -> list[str]:
    text = (ROOT / "docs" / "vision.md").read_text(encoding="utf-8")
    section = text.split("### Try it on the simulated cell", 1)[1]
    block = re.search(r"```sh\n(.*?)```", section, re.S)
    assert block is not None, "the section has its shell block"
    return [ln for ln in block.group(1).splitlines() if ln.strip()]


def shell_env() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"  # this venv's aioadept
    return env


@pytest.mark.timeout(120)
def test_the_documented_calibration_writes_the_world_cameras_pose(tmp_path):
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    lines = documented_lines()
    assert any(ln.startswith("aioadept calibrate --config") for ln in lines), lines
    for line in lines:
        res = subprocess.run(["bash", "-c", line], cwd=tmp_path, env=shell_env(), capture_output=True, text=True,
                             timeout=100)
        assert res.returncode == 0, (line, res.stderr[-2000:])
    written = tmp_path / "my-cell.toml"
    data = tomllib.loads(written.read_text(encoding="utf-8"))
    cal = CameraCalibration.from_table(data["calibration"])
    assert data["calibration"]["views"] == 12 and cal.rms_px < 0.5
    truth = load_world(written).camera.pose()  # where the sim's world camera really is
    err_mm, err_deg = pose_error(cal.pose, truth)
    assert err_mm <= 1.0 and err_deg <= 0.1, (err_mm, err_deg)
    assert data["pickplace"]["parts"] == 6 and "tool_marker" in data["world"]  # the other tables kept
    print(f"calibration error {err_mm:.3f} mm, {err_deg:.4f} deg, rms {cal.rms_px} px")


@pytest.mark.timeout(60)
def test_a_write_path_in_a_missing_folder_is_refused_before_anything_moves(tmp_path):
    # port 9 (discard): nothing listens; a run that got past the checks would fail with exit 1, not 2
    for write in (tmp_path / "no" / "cell.toml", tmp_path):
        res = subprocess.run([sys.executable, "-m", "aioadept", "calibrate", "--robot", "127.0.0.1:9", "--write",
                              str(write)], capture_output=True, text=True, timeout=30)
        lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
        assert res.returncode == 2 and len(lines) == 1 and str(write) in lines[0], res.stderr
    assert not (tmp_path / "no").exists()


@pytest.mark.timeout(60)
def test_a_cell_whose_vision_node_cannot_see_a_tool_marker_is_refused_before_anything_starts(tmp_path):
    cell = tmp_path / "cell.toml"
    shutil.copy(ROOT / "examples" / "world-cell.toml", cell)  # source = "virtual": no world camera, no tool marker
    res = subprocess.run([sys.executable, "-m", "aioadept", "calibrate", "--config", str(cell)], cwd=tmp_path,
                         capture_output=True, text=True, timeout=30)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2 and len(lines) == 1 and "tool_marker" in lines[0], res.stderr
    assert not (tmp_path / "runs").exists()  # nothing started
