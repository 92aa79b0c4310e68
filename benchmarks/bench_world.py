"""What the simulated world costs, each against its neighbour measured in the same run.

- **render**: one frame of the world's fixed camera (``WorldView.render``: the example cell's three parts with
  their ArUco labels, lens blur, sensor noise; 1024 x 768 mono8) vs one frame of the focus app's virtual camera
  (``VirtualCamera.render`` of the calibration target near focus). Both run on the acquisition thread per frame.
- **sample**: one ``world.state`` sample, built and serialised (``world_state_sample(...).to_bytes()``), with a part
  in the hand while the arm moves, vs one ``robot.state`` sample of the same controller at the same instants. The
  sim's publisher builds one of each per period (100 Hz).

No sockets, no processes. Prints one JSON object. Usage: ``python benchmarks/bench_world.py [--rounds 200]``.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from pathlib import Path

from verdicts import verdict

from aioadept.cell.config import CellConfig
from aioadept.geometry import Pose
from aioadept.sim.controller import Controller
from aioadept.sim.server import robot_state_sample, world_state_sample
from aioadept.world import World
from aioadept.vision.virtual_camera import paper_approach_pose, paper_camera
from aioadept.vision.world_camera import WorldView

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "world-cell.toml"


def p50_s(fn, rounds: int) -> float:
    times = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=200)
    args = ap.parse_args()
    world_cfg = CellConfig.from_toml(EXAMPLE).world
    assert world_cfg is not None

    view = WorldView(world_cfg, seed=0)
    parts = World(world_cfg).snapshot(0.0).parts
    cam = paper_camera(seed=0)
    near_focus = paper_approach_pose() @ Pose(z=19.0)
    render_world = p50_s(lambda: view.render(parts), args.rounds)
    render_target = p50_s(lambda: cam.render(near_focus), args.rounds)

    # a part in the hand, the arm on its way 100 mm up: every sample computes the tool pose and the held part
    spec = world_cfg.parts[0]
    ctl = Controller(world=World(world_cfg))
    grip = Pose(spec.x_mm, spec.y_mm, world_cfg.table_z_mm + 10.0, 0.0, 180.0, 0.0)
    for wake in ctl.move_pose(grip):
        ctl.now_s = wake
    ctl.now_s = ctl.trajectory.t_rest_s
    ctl.io.hand_now("close", ctl.now_s)
    assert ctl.world is not None and ctl.world.held == spec.id
    for wake in ctl.move_pose(grip @ Pose(z=-100.0)):
        ctl.now_s = wake
    t0, t1 = ctl.now_s, ctl.trajectory.t_rest_s
    instants = [t0 + (t1 - t0) * i / args.rounds for i in range(args.rounds)]
    it = iter(instants * 2)
    world_sample = p50_s(lambda: world_state_sample(ctl, next(it), 0.0, [0]).to_bytes(), args.rounds)
    it = iter(instants * 2)
    robot_sample = p50_s(lambda: robot_state_sample(ctl, next(it), 0.0, [0]).to_bytes(), args.rounds)

    print(json.dumps({
        "python": platform.python_version(), "rounds": args.rounds, "parts": len(parts),
        "render_ms_p50": {"world": render_world * 1e3, "virtual_target": render_target * 1e3},
        "sample_us_p50": {"world": world_sample * 1e6, "robot": robot_sample * 1e6},
        "verdicts": [
            verdict("world camera frame render", render_world * 1e3, render_target * 1e3, unit="ms",
                    goal="figure <= 66.7 ms (15 fps)", passed=render_world * 1e3 <= 66.7),
            verdict("world.state sample, part held, arm moving", world_sample * 1e6, robot_sample * 1e6, unit="us",
                    goal="figure <= 1000 us (10 % of a 100 Hz period)", passed=world_sample * 1e6 <= 1000.0),
        ],
    }, indent=2))


if __name__ == "__main__":
    main()
