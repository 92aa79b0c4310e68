"""Many robots in one cell, as a user runs it: ``aioadept demo --config FILE`` with two robots
and two cameras, real processes on loopback, over one Zenoh router (and over ZeroMQ); the presence of one camera
among several, killed and restarted; and the cell file's mistakes on the command line."""

from __future__ import annotations

import csv
import importlib.util
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from test_demo import _live_cmdlines

AIOADEPT = [sys.executable, "-m", "aioadept"]
HAS_ZENOH = importlib.util.find_spec("zenoh") is not None

TWO_ROBOTS = """
[bus]
transport = "{transport}"
cell = "twotest"
zenoh_router = "tcp/127.0.0.1:0"

[run]
out_dir = "{out}"

[focus]
delta_z_mm = 2.0

[[robots]]
name = "r1"

[[robots]]
name = "r2"

[[cameras]]
name = "cam1"
robot = "r1"
focus_offset_mm = 12.0

[[cameras]]
name = "cam2"
robot = "r2"
focus_offset_mm = 22.0
"""


def _span(run: Path) -> tuple[float, float]:
    """First send and last ack of a robot's run, on the coordinating process's loop clock (shared by all robots)."""
    with open(run / "robot.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return min(float(r["t_send_s"]) for r in rows), max(float(r["t_recv_s"]) for r in rows)


@pytest.mark.timeout(200)
@pytest.mark.parametrize("transport", ["zenoh", "zeromq"])
def test_two_robots_each_find_their_own_cameras_plane_at_the_same_time_and_leave_no_process(tmp_path, transport):
    if transport == "zenoh" and not HAS_ZENOH:
        pytest.skip("the [zenoh] extra (eclipse-zenoh) is not installed")
    cell = tmp_path / "two.toml"
    cell.write_text(TWO_ROBOTS.format(transport=transport, out=tmp_path / "runs"))
    proc = subprocess.run([*AIOADEPT, "demo", "--config", str(cell), "--time-scale", "20", "--no-record"],
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (run_dir,) = (tmp_path / "runs").iterdir()
    summary = json.loads((run_dir / "multi.json").read_text())
    assert summary["transport"] == transport and [r["robot"] for r in summary["robots"]] == ["r1", "r2"]
    if transport == "zenoh":  # the application saw every node come (before the robots moved) and go
        seen = {(e["node"], e["alive"]) for e in summary["presence"]}
        nodes = {(n, alive) for n in ("r1", "r2", "cam1", "cam2") for alive in (True, False)}
        assert seen == nodes | {("app", True)}, seen  # the application's own token goes with its session
    for robot, camera, plane in (("r1", "cam1", 12.0), ("r2", "cam2", 22.0)):
        sub = run_dir / robot
        focus = json.loads((sub / "focus.json").read_text())
        # 10 mm apart: a robot served by the other robot's camera (or following its state) would find the wrong one.
        assert abs(focus["peak_offset_mm"] - plane) <= 2.0, (robot, focus["peak_offset_mm"])
        for name in ("robot.csv", "vision.csv", "run.json", "summary.json", "fig10_gantt.png"):
            assert (sub / name).stat().st_size > 0, (robot, name)
        assert f"{robot} ({camera}): focal plane" in proc.stdout
        started = [(sub / "logs" / f).read_text().splitlines()[0].removeprefix("$ ") for f in ("sim.log",
                                                                                                "vision.log")]
        if transport == "zenoh":  # each node on its own keys, named in its liveliness token
            assert f"--state-endpoint zenoh:aioadept/twotest/{robot}/state" in started[0]
            assert started[0].endswith(f"--node {robot}") and started[1].endswith(f"--node {camera}")
            assert f"--request-endpoint zenoh:aioadept/twotest/{camera}/request" in started[1]
            assert f"--state-endpoint zenoh:aioadept/twotest/{robot}/state" in started[1]
        live = _live_cmdlines()
        for cmd in started:
            assert cmd not in live, f"still running: {cmd}"
    (a0, a1), (b0, b1) = _span(run_dir / "r1"), _span(run_dir / "r2")
    assert a0 < b1 and b0 < a1, "the two robots' runs did not overlap in time"


@pytest.mark.timeout(90)
@pytest.mark.skipif(not HAS_ZENOH, reason="the [zenoh] extra (eclipse-zenoh) is not installed")
async def test_a_killed_camera_of_several_is_seen_gone_and_back_within_1_s_while_the_others_stay(tmp_path):
    from aioadept.apps.processes import NodeProcess
    from aioadept.bus import Communicator
    from aioadept.bus.presence import NodeWatcher
    from aioadept.testing.nodes import running_node

    from bustransports import start_zenoh_router

    router = start_zenoh_router()

    def argv(cam: str) -> list[str]:
        return ["vision", "--transport", "zenoh", "--zenoh-connect", router, "--cell", "multipres", "--node", cam,
                "--request-endpoint", f"zenoh:aioadept/multipres/{cam}/request",
                "--response-endpoint", f"zenoh:aioadept/multipres/{cam}/response",
                "--state-endpoint", "none", "--graph", "noop"]

    async with NodeWatcher("multipres") as watcher:
        cam1 = NodeProcess("cam1", argv("cam1"), log_path=tmp_path / "cam1.log")
        await cam1.start()
        try:
            async with running_node(*argv("cam2"), log_path=tmp_path / "cam2.log", expect_clean_exit=False) as cam2:
                await watcher.wait_for("cam1", True, timeout_s=1.0)
                await watcher.wait_for("cam2", True, timeout_s=1.0)
                assert {"cam1", "cam2"} <= watcher.alive and "vision" not in watcher.alive
                async with Communicator(cam1.ready["request"], cam1.ready["response"], timeout_s=5.0) as c1, \
                        Communicator(cam2.ready["request"], cam2.ready["response"], timeout_s=5.0) as c2:
                    assert "error" not in (await c1.request("VisionRequest", {})).attributes
                    cam1.proc.send_signal(signal.SIGKILL)
                    t_kill = time.monotonic()
                    await watcher.wait_for("cam1", False, timeout_s=1.0)
                    gone_s = time.monotonic() - t_kill
                    await cam1.proc.wait()
                    assert "cam2" in watcher.alive  # the others stay, and keep serving
                    assert "error" not in (await c2.request("VisionRequest", {})).attributes
                    async with running_node(*argv("cam1"), log_path=tmp_path / "cam1b.log", expect_clean_exit=False):
                        t_ready = time.monotonic()
                        await watcher.wait_for("cam1", True, timeout_s=1.0)
                        seen_s = time.monotonic() - t_ready
                        assert "error" not in (await c1.request("VisionRequest", {})).attributes
        finally:
            await cam1.stop()
    assert gone_s < 1.0 and seen_s < 1.0


@pytest.mark.timeout(30)
def test_a_mistake_in_a_cell_of_several_robots_is_one_line_and_starts_nothing(tmp_path):
    cell = tmp_path / "bad.toml"
    cell.write_text(TWO_ROBOTS.format(transport="zenoh", out=tmp_path / "runs").replace(
        'name = "r2"', 'name = "r2"\nmonitor_speed = 0'))
    proc = subprocess.run([*AIOADEPT, "demo", "--config", str(cell)], capture_output=True, text=True, timeout=25)
    assert proc.returncode == 2
    (line,) = proc.stderr.strip().splitlines()
    assert str(cell) in line and '[[robots]] name = "r2": monitor_speed = 0' in line and "Traceback" not in line
    assert not (tmp_path / "runs").exists()
    proc = subprocess.run([*AIOADEPT, "focus", "--config", str(cell)], capture_output=True, text=True, timeout=25)
    assert proc.returncode == 2 and "only `aioadept demo --config FILE` runs" in proc.stderr
    good = tmp_path / "good.toml"
    good.write_text(TWO_ROBOTS.format(transport="zenoh", out=tmp_path / "runs"))
    proc = subprocess.run([*AIOADEPT, "demo", "--config", str(good), "--view"], capture_output=True, text=True,
                          timeout=25)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1 and "--view" in proc.stderr
    proc = subprocess.run([*AIOADEPT, "demo", "--config", str(good), "--speed", "0"], capture_output=True,
                          text=True, timeout=25)
    assert proc.returncode == 2 and "--speed 0: expected" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "runs").exists()


@pytest.mark.timeout(30)
def test_a_node_name_needs_zenoh_and_is_one_key_chunk():
    for extra, text in ((["--node", "r1"], "--node needs --transport zenoh"),
                        (["--transport", "zenoh", "--node", "a/b"], "--node 'a/b'")):
        proc = subprocess.run([*AIOADEPT, "sim", "--port", "0", *extra], capture_output=True, text=True, timeout=25)
        assert proc.returncode == 2 and text in proc.stderr and "Traceback" not in proc.stderr, proc.stderr


@pytest.mark.timeout(150)
async def test_one_sigint_stops_every_robot_of_the_cell_then_every_node_and_exits_130(tmp_path):
    import asyncio
    import os

    from aioadept.ports import free_port
    from test_sigint import SLOW_SPEED, StateWatch, _finish, _gone, _spawn, at_rest, moving_at

    states = [f"tcp://127.0.0.1:{free_port()}" for _ in range(2)]
    cell = tmp_path / "two.toml"
    cell.write_text(TWO_ROBOTS.format(transport="zeromq", out=tmp_path / "runs").replace(
        'name = "r1"', f'name = "r1"\nstate_endpoint = "{states[0]}"').replace(
        'name = "r2"', f'name = "r2"\nstate_endpoint = "{states[1]}"').replace(
        "focus_offset_mm = 12.0", "focus_offset_mm = 200.0").replace("focus_offset_mm = 22.0",
                                                                     "focus_offset_mm = 200.0"))
    watches = [StateWatch(s) for s in states]  # connect before the sims bind: ZeroMQ retries
    try:
        proc = await _spawn("demo", "--config", str(cell), "--speed", str(SLOW_SPEED), "--delta-z", "40",
                            "--max-steps", "5", "--no-record", "--no-analyze")
        try:
            for w in watches:  # both arms in a slow 40 mm step at once
                await w.until(moving_at(SLOW_SPEED), f"moving at {SLOW_SPEED} %", timeout_s=60)
            t_kill = asyncio.get_running_loop().time()
            os.kill(proc.pid, signal.SIGINT)
            rests = [await w.until(at_rest, "at rest", timeout_s=5) for w in watches]
            out, err = await _finish(proc, timeout_s=30)
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
    finally:
        for w in watches:
            w.close()
    for t_rest, _rest in rests:
        assert t_rest - t_kill < 2.0, f"at rest {t_rest - t_kill:.3f} s after SIGINT"
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted: robot stopped" in err
    for s in states:
        await _gone(s)  # each robot's sim and camera node (both have its state endpoint in their command line)
