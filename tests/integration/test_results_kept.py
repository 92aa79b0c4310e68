"""Results are never lost: ``aioadept focus`` as a process, with a run folder it cannot write.

Tests may run as root, where a read-only folder (chmod) does not stop writes. So the full disk is made real with
the file-size limit (``RLIMIT_FSIZE``, which binds root too; Python ignores SIGXFSZ, so a write past it fails with
EFBIG): the calibration still runs, the result is printed, the error names each file not written, and no file is
left half written. A run folder that cannot be created at all (its parent is a file) is refused before the robot
is touched.
"""

from __future__ import annotations

import asyncio
import json
import resource
import sys
from pathlib import Path

import pytest

from aioadept.client import RobotClient
from aioadept.testing.nodes import running_node

AIOADEPT = [sys.executable, "-m", "aioadept"]
pytestmark = pytest.mark.timeout(90)


def _limit_file_size(max_bytes: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (max_bytes, max_bytes))

    return apply


async def _focus(sim, vision, out: Path, *, preexec_fn=None) -> tuple[int, str, str]:
    proc = await asyncio.create_subprocess_exec(
        *AIOADEPT, "focus", "--robot", f"127.0.0.1:{sim.ready['port']}", "--request-endpoint", vision.ready["request"],
        "--response-endpoint", vision.ready["response"], "--out", str(out), "--no-analyze", "--delta-z", "2.5",
        stdin=asyncio.subprocess.DEVNULL, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
        preexec_fn=preexec_fn)
    try:
        async with asyncio.timeout(60):
            out_b, err_b = await proc.communicate()
    finally:
        if proc.returncode is None:  # a hung run must not outlive the test
            proc.kill()
            await proc.wait()
    assert proc.returncode is not None
    return proc.returncode, out_b.decode(errors="replace"), err_b.decode(errors="replace")


async def test_a_full_disk_still_prints_the_result_and_names_what_was_not_written(tmp_path):
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0", "--time-scale", "10",
                            log_path=tmp_path / "sim.log") as sim, \
            running_node("vision", "--state-endpoint", sim.ready["state"], "--request-endpoint", "tcp://127.0.0.1:0",
                         "--response-endpoint", "tcp://127.0.0.1:0", "--focus-offset-mm", "16", "--policy", "after",
                         log_path=tmp_path / "vision.log") as vision:
        # 3 KiB per file: focus.json (the result) fits, robot.csv (every message of the run) does not.
        code, out, err = await _focus(sim, vision, tmp_path / "runs", preexec_fn=_limit_file_size(3072))
    assert code == 4, out + err
    assert "Traceback" not in err
    assert "inspection-start pose" in out and "x=" in out  # the result reached the operator
    one_line = " ".join(err.split())
    assert "NOT fully saved" in one_line and "robot.csv (File too large)" in one_line and "run.json" in one_line
    (run_dir,) = (tmp_path / "runs").iterdir()
    focus = json.loads((run_dir / "focus.json").read_text())
    assert focus["peak_offset_mm"] == pytest.approx(16, abs=2.5)
    names = sorted(p.name for p in run_dir.iterdir())
    assert "robot.csv" not in names and "run.json" not in names, names  # not there rather than half there
    assert not [n for n in names if n.endswith(".tmp")], names
    for name in names:
        if name.endswith(".csv"):
            text = (run_dir / name).read_text()
            assert text.endswith("\n"), f"{name} is cut short"


async def test_a_run_folder_that_cannot_be_created_refuses_before_the_robot_moves(tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0", "--time-scale", "10",
                            log_path=tmp_path / "sim.log") as sim:
        async with RobotClient("127.0.0.1", int(sim.ready["port"])) as rc:
            before = await rc.here()
        proc = await asyncio.create_subprocess_exec(
            *AIOADEPT, "focus", "--robot", f"127.0.0.1:{sim.ready['port']}", "--out", str(blocker / "runs"),
            "--no-analyze", stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
        async with asyncio.timeout(30):
            _out, err_b = await proc.communicate()
        async with RobotClient("127.0.0.1", int(sim.ready["port"])) as rc:
            after = await rc.here()
    err = err_b.decode()
    assert proc.returncode == 2, err
    assert "cannot create a run folder" in err and "nothing was started" in err and "Traceback" not in err
    assert before == after
