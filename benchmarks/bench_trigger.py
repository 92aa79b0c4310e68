"""Focus-loop cycle time: software-triggered camera vs the free-running 15 fps camera (issue 12), real time.

Starts ``aioadept sim`` (time scale 1) and, for each configuration, an ``aioadept vision`` process, then runs the
paper's focus loop (MoveToolZ(delta_z) at the demo's approach speed, then one VisionRequest) for ``--steps``
cycles from the approach pose. Per cycle: the motion time (cmdexec_joined) and the request time. The floor of a
cycle is motion + exposure + readout + graph time (from the responses); the goal is median cycle <= 1.10 x floor.

Configurations (same run, same sim): ``free`` = ``--trigger free --fps 15 --policy after`` (the baseline: a request
waits for the next free-running frame), ``triggered`` = the default (``--trigger auto``: the request triggers its
exposure). Prints one JSON object with a top-level ``verdicts`` list.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from verdicts import verdict  # noqa: E402

from aioadept import MoveJoints, MoveRelJoints, MoveRelTool, MoveToolZ, SetSpeed  # noqa: E402
from aioadept.apps.focus import FocusParams  # noqa: E402
from aioadept.bus.communicator import Communicator  # noqa: E402
from aioadept.client import RobotClient  # noqa: E402
from aioadept.testing.nodes import running_node  # noqa: E402


async def run_config(sim: dict, name: str, vision_args: list[str], steps: int, log_dir: Path) -> dict:
    params = FocusParams()
    async with running_node("vision", "--state-endpoint", sim["state"], "--request-endpoint", "tcp://127.0.0.1:0",
                            "--response-endpoint", "tcp://127.0.0.1:0", *vision_args,
                            log_path=log_dir / f"vision-{name}.log") as vis:
        async with RobotClient(sim["host"], int(sim["port"])) as robot, \
                Communicator(vis.ready["request"], vis.ready["response"], timeout_s=5.0) as comm:
            await robot.cmdexec(MoveJoints([0, -90, 180, 0, 90, 0]), MoveRelJoints([-90, 60, 30, -90, 0, 0]),
                                MoveRelTool([40, -25, 185, 0, 0, 0]))
            await comm.request("VisionRequest", {})  # both ZeroMQ paths up
            cycles, motions, floors = [], [], []
            for _ in range(steps):
                t0 = time.perf_counter()
                await robot.cmdexec_joined(SetSpeed(params.approach_speed), MoveToolZ(params.delta_z_mm))
                t1 = time.perf_counter()
                resp = await comm.request("VisionRequest", {})
                t2 = time.perf_counter()
                a = resp.attributes
                cycles.append((t2 - t0) * 1e3)
                motions.append((t1 - t0) * 1e3)
                floors.append((t1 - t0) * 1e3 + a.get("exposure_ms", 0.0) + a.get("readout_ms", 0.0)
                              + a.get("proc_time_ms", 0.0))
            await robot.cmdexec_joined(SetSpeed(50), MoveToolZ(-params.delta_z_mm * steps))
    return {"cycle_ms_p50": statistics.median(cycles), "motion_ms_p50": statistics.median(motions),
            "floor_ms_p50": statistics.median(floors), "vision_ms_p50": statistics.median(
                c - m for c, m in zip(cycles, motions)), "cycles": len(cycles)}


async def main_async(args: argparse.Namespace) -> dict:
    log_dir = Path(args.log_dir)
    log_dir.mkdir(parents=True, exist_ok=True)
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0",
                            log_path=log_dir / "sim.log") as sim:
        free = await run_config(sim.ready, "free", ["--trigger", "free", "--fps", "15", "--policy", "after"],
                                args.steps, log_dir)
        trig = await run_config(sim.ready, "triggered", [], args.steps, log_dir)
    ratio_trig = trig["cycle_ms_p50"] / trig["floor_ms_p50"]
    ratio_free = free["cycle_ms_p50"] / free["floor_ms_p50"]
    return {
        "benchmark": "trigger", "steps": args.steps, "free_running_15fps": free, "software_trigger": trig,
        "verdicts": [
            verdict("focus cycle p50, software trigger vs its floor", trig["cycle_ms_p50"], trig["floor_ms_p50"],
                    unit="ms", ratio=ratio_trig, goal="ratio <= 1.10", passed=ratio_trig <= 1.10),
            verdict("focus cycle p50, free-running 15 fps vs its floor (before)", free["cycle_ms_p50"],
                    free["floor_ms_p50"], unit="ms", ratio=ratio_free),
            verdict("focus cycle p50, triggered vs free-running", trig["cycle_ms_p50"], free["cycle_ms_p50"],
                    unit="ms", goal="ratio < 1", passed=trig["cycle_ms_p50"] < free["cycle_ms_p50"]),
        ],
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--steps", type=int, default=20)
    p.add_argument("--quick", action="store_true", help="5 steps")
    p.add_argument("--log-dir", default="runs/bench-trigger-logs")
    args = p.parse_args()
    if args.quick:
        args.steps = 5
    print(json.dumps(asyncio.run(main_async(args)), indent=2))


if __name__ == "__main__":
    main()
