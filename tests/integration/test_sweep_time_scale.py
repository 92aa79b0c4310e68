"""The sweep moves the tool at the speed its log says, against a sim started on its own at ``--time-scale 5``: a real ``aioadept sim`` process, a vision node and ``aioadept focus --mode sweep`` whose cell file
says nothing of the time scale; the tool's speed is read from the sim's own state stream, never from the app.

Before, the sweep divided its speed by the time scale only when it started the sim itself: the log said 200 mm/s
while the tool moved at 1000 mm/s, and the sweep failed now and then ("no focal plane after 4 sweeps").
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import re
import sys
from itertools import pairwise

import pytest

from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import Subscriber
from aioadept.testing.nodes import running_node

AIOADEPT = [sys.executable, "-m", "aioadept"]
TIME_SCALE = 5.0


@pytest.mark.timeout(120)
async def test_a_sweep_against_a_separately_started_fast_sim_moves_at_the_logged_speed(tmp_path):
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0", "--time-scale",
                            str(TIME_SCALE), log_path=tmp_path / "sim.log") as sim, \
            running_node("vision", "--state-endpoint", sim.ready["state"], "--request-endpoint", "tcp://127.0.0.1:0",
                         "--response-endpoint", "tcp://127.0.0.1:0", "--focus-offset-mm", "21.3",
                         log_path=tmp_path / "vision.log") as vision:
        cfg = tmp_path / "cell.toml"
        cfg.write_text(f"[robot]\nstate_endpoint = \"{sim.ready['state']}\"\n[focus]\nmode = \"sweep\"\n"
                       "[run]\nanalyze = false\nrecord = false\n")
        samples: list[RobotState] = []
        sub = Subscriber(sim.ready["state"], topics=[ROBOT_STATE_TOPIC])

        async def follow() -> None:
            while True:
                _topic, payload = await sub.recv()
                samples.append(RobotState.from_bytes(payload))

        follower = asyncio.create_task(follow())
        try:
            proc = await asyncio.create_subprocess_exec(
                *AIOADEPT, "focus", "--config", str(cfg), "--robot", f"127.0.0.1:{sim.ready['port']}",
                "--request-endpoint", vision.ready["request"], "--response-endpoint", vision.ready["response"],
                "--out", str(tmp_path / "runs"), stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
                env={**os.environ, "COLUMNS": "400"})
            out, err = await asyncio.wait_for(proc.communicate(), 60)
        finally:
            follower.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await follower
            sub.close()
    log = " ".join((out + err).decode().split())
    logged = [(int(m[1]), float(m[2])) for m in re.finditer(r"sweep \d+ \S+ mm at (\d+) % \((?:tool )?(\d+) mm/s", log)]
    assert logged, log
    pct, logged_mm_s = logged[0]

    # The tool, as the sim publishes it, moves at the logged speed on the first sweep's line (its program speed).
    def on_line(s: RobotState) -> bool:
        return s.in_motion and s.speed_pct == pct

    speeds = [b.pose.translation_distance_mm(a.pose) / (b.wall_time_s - a.wall_time_s)
              for a, b in pairwise(samples) if on_line(a) and on_line(b) and b.wall_time_s > a.wall_time_s]
    assert speeds, f"no samples of the line at {pct} %"
    measured = max(speeds)
    assert abs(measured - logged_mm_s) <= 0.15 * logged_mm_s, (measured, logged_mm_s)

    # The run found the plane, and the log says the time scale and where it came from.
    assert proc.returncode == 0, log
    assert f"robot time scale {TIME_SCALE:g}, as the robot's status reports it" in log
    assert f"at time scale {TIME_SCALE:g}" in log
    (run_dir,) = (tmp_path / "runs").iterdir()
    plans = json.loads((run_dir / "focus.json").read_text())["sweep"]["plans"]
    assert (pct, logged_mm_s) == (plans[0]["speed_pct"], plans[0]["speed_mm_s"])
