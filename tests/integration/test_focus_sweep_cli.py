"""``aioadept focus --mode sweep`` as a user runs it: a real process against a real sim and vision node.

It finds the plane between the steps and writes the sweep's focus.json; a SIGINT during the sweep's line stops the
arm (read from the sim's own state stream, never from the app) and nothing moves afterwards: no retract, no next
sweep, no move to a plane.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import signal
import sys
from pathlib import Path

import pytest

from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import Subscriber
from aioadept.testing.nodes import running_node

AIOADEPT = [sys.executable, "-m", "aioadept"]


@contextlib.asynccontextmanager
async def cell(tmp_path: Path, focus_offset_mm: float):
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0",
                            log_path=tmp_path / "sim.log") as sim, \
            running_node("vision", "--state-endpoint", sim.ready["state"], "--request-endpoint", "tcp://127.0.0.1:0",
                         "--response-endpoint", "tcp://127.0.0.1:0", "--focus-offset-mm", str(focus_offset_mm),
                         log_path=tmp_path / "vision.log") as vision:
        yield sim, vision


def focus_argv(sim, vision, tmp_path: Path, focus_lines: str = "") -> list[str]:
    cfg = tmp_path / "cell.toml"
    cfg.write_text(f"[robot]\nstate_endpoint = \"{sim.ready['state']}\"\n[focus]\nmode = \"sweep\"\n{focus_lines}"
                   "[run]\nanalyze = false\nrecord = false\n")
    return ["focus", "--config", str(cfg), "--robot", f"127.0.0.1:{sim.ready['port']}", "--request-endpoint",
            vision.ready["request"], "--response-endpoint", vision.ready["response"], "--out", str(tmp_path / "runs")]


@pytest.mark.timeout(90)
async def test_focus_mode_sweep_finds_the_plane_and_says_how(tmp_path):
    async with cell(tmp_path, 17.7) as (sim, vision):
        proc = await asyncio.create_subprocess_exec(*AIOADEPT, *focus_argv(sim, vision, tmp_path),
                                                    stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
        out, err = await asyncio.wait_for(proc.communicate(), 60)
    assert proc.returncode == 0, err.decode()
    (run_dir,) = (tmp_path / "runs").iterdir()
    result = json.loads((run_dir / "focus.json").read_text())
    assert result["mode"] == "sweep" and result["pose_source"] == "state-stream"
    assert abs(result["peak_offset_mm"] - 17.7) <= 0.1 and result["search_s"] > 0
    assert "focal plane 17.6" in out.decode() or "focal plane 17.7" in out.decode()


@pytest.mark.timeout(90)
async def test_sigint_during_the_sweep_stops_the_arm_and_nothing_moves_after(tmp_path):
    # A slow sweep (40 mm/s, 2 %: 1 s for 40 mm) so the signal lands in the middle of its line.
    async with cell(tmp_path, 21.3) as (sim, vision):
        sub = Subscriber(sim.ready["state"], topics=[ROBOT_STATE_TOPIC])

        async def state() -> tuple[float, RobotState]:
            _topic, payload = await sub.recv()
            return asyncio.get_running_loop().time(), RobotState.from_bytes(payload)

        try:
            proc = await asyncio.create_subprocess_exec(
                *AIOADEPT, *focus_argv(sim, vision, tmp_path, "sweep_max_speed_mm_s = 40.0\n"),
                stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
            try:
                async with asyncio.timeout(60):
                    while True:  # the sweep's line at 2 % is under way
                        _t, st = await state()
                        if st.in_motion and st.speed_pct == 2:
                            break
                await asyncio.sleep(0.3)
                t_kill = asyncio.get_running_loop().time()
                os.kill(proc.pid, signal.SIGINT)
                async with asyncio.timeout(5):
                    while True:
                        t_rest, rest = await state()
                        if not rest.in_motion:
                            break
                out, err = await asyncio.wait_for(proc.communicate(), 20)
                later = []
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(1.0):
                        while True:
                            later.append((await state())[1])
            finally:
                if proc.returncode is None:
                    proc.kill()
                    await proc.wait()
        finally:
            sub.close()
    assert t_rest - t_kill < 2.0
    assert later and not [s for s in later if s.in_motion or s.pose.translation_distance_mm(rest.pose) > 0.01]
    assert proc.returncode == 130, err.decode()
    assert "Traceback" not in err.decode() and "interrupted: robot stopped" in err.decode()
    (run_dir,) = (tmp_path / "runs").iterdir()
    assert json.loads((run_dir / "focus.json").read_text()) == {"error": "interrupted"}
