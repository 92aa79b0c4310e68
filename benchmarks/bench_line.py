"""What a straight line costs the pure controller, against a joint move between the same ends.

- **plan**: the time ``move_to_s`` spends before its ack (the line sampled every 1 mm / 0.5 deg, each sample
  solved with the inverse kinematics) vs ``move_to`` (one inverse kinematics), both for a 300 mm move turning
  30 deg. It holds the single executor, so it adds to that ack's latency.
- **query**: one ``Trajectory.position`` while the motion runs (what every ack and every state-stream sample costs)
  on the line vs on the joint move.
- **deviation**: the largest distance of the tool from the line, sampled at 2000 instants (the issue asks for at
  most 0.5 mm), and, for scale, the joint move's.
- **planner**: ``plan_tool_line`` (the samples solved in numpy arrays) against the per-sample loop it replaced
  (``batch=False``: one scalar inverse kinematics per sample, the reference), rounds interleaved, for the 300 mm
  line and a 1000 mm one turning 90 deg; and the largest joint difference between the two plans (deg). The plan
  runs on the sim server's event loop, where a ``stop`` waits for it: the goal is a 300 mm line under 2 ms. The
  same for a Cobra s600 (``--robot-model cobra-s600``), a 400 mm line turning 30 deg.

No sockets, no processes: the controller with its time passed in. Prints one JSON object.
Usage: ``python benchmarks/bench_line.py [--rounds 20]``.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time

import numpy as np
from verdicts import verdict

from aioadept.geometry import Pose
from aioadept.robots import model
from aioadept.robots import viper_s850 as kin
from aioadept.sim.controller import Controller
from aioadept.sim.line import plan_tool_line

A = Pose(400.0, -150.0, 400.0, 0.0, 180.0, 0.0)
B = Pose(400.0, 150.0, 400.0, 0.0, 180.0, 30.0)
LONG = (Pose(350.0, -500.0, 300.0, 0.0, 180.0, 0.0), Pose(350.0, 500.0, 300.0, 0.0, 180.0, 90.0))
COBRA = (Pose(350.0, -150.0, 250.0, 0.0, 180.0, 0.0), Pose(250.0, 250.0, 280.0, 0.0, 180.0, 30.0))


def at_a() -> Controller:
    ctl = Controller()
    for wake in ctl.move_pose(A):
        ctl.now_s = wake
    ctl.now_s = ctl.trajectory.t_rest_s + 1.0
    return ctl


def start(ctl: Controller, straight: bool) -> float:
    """Run the motion instruction up to its start; return how long that took (s)."""
    t0 = time.perf_counter()
    gen = ctl.move_line(B) if straight else ctl.move_pose(B)
    for _ in gen:
        pass
    return time.perf_counter() - t0


def off_line_mm(p: Pose) -> float:
    return float(np.hypot(p.x - 400.0, p.z - 400.0))


def measure(straight: bool, rounds: int) -> dict[str, float]:
    plans, queries, worst = [], [], 0.0
    for _ in range(rounds):
        ctl = at_a()
        plans.append(start(ctl, straight))
        seg = ctl.trajectory._segments[-1]
        ts = np.linspace(seg.t0_s, seg.t_end_s, 2000)
        t0 = time.perf_counter()
        positions = [ctl.trajectory.position(float(t)) for t in ts]
        queries.append((time.perf_counter() - t0) / len(ts))
        worst = max(worst, max(off_line_mm(kin.forward(q)) for q in positions[::10]))
    return {"plan_ms_p50": statistics.median(plans) * 1e3, "query_us_p50": statistics.median(queries) * 1e6,
            "max_off_line_mm": worst}


def measure_planner(a: Pose, b: Pose, rounds: int, name: str = "viper-s850") -> dict[str, float]:
    """The array planner vs the per-sample reference on the line a -> b, rounds interleaved (times in ms)."""
    m = model(name)
    start = m.inverse(a, m.home_deg)
    new, ref, ratios, diff = [], [], [], 0.0
    for _ in range(rounds):
        t0 = time.perf_counter()
        fast = plan_tool_line(start, b, model=m)
        t1 = time.perf_counter()
        slow = plan_tool_line(start, b, batch=False, model=m)
        t2 = time.perf_counter()
        new.append(t1 - t0)
        ref.append(t2 - t1)
        ratios.append((t1 - t0) / (t2 - t1))
        diff = max(diff, float(np.abs(fast.joints_deg - slow.joints_deg).max()))
    return {"samples": len(fast.s), "new_ms_p50": statistics.median(new) * 1e3,
            "reference_ms_p50": statistics.median(ref) * 1e3, "ratio_p50": statistics.median(ratios),
            "max_joint_diff_deg": diff}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=20)
    args = ap.parse_args()
    line = measure(True, args.rounds)
    joint = measure(False, args.rounds)
    plan300 = measure_planner(A, B, args.rounds)
    plan1000 = measure_planner(*LONG, args.rounds)
    cobra = measure_planner(*COBRA, args.rounds, "cobra-s600")
    diff = max(plan300["max_joint_diff_deg"], plan1000["max_joint_diff_deg"], cobra["max_joint_diff_deg"])
    print(json.dumps({
        "python": platform.python_version(), "rounds": args.rounds, "line": line, "joint": joint,
        "planner": {"300mm": plan300, "1000mm": plan1000, "cobra-s600": cobra},
        "verdicts": [
            verdict("300 mm line planned: arrays vs per-sample loop", plan300["new_ms_p50"],
                    plan300["reference_ms_p50"], unit="ms", ratio=plan300["ratio_p50"], goal="figure <= 2 ms",
                    passed=plan300["new_ms_p50"] <= 2.0),
            verdict("1000 mm line planned: arrays vs per-sample loop", plan1000["new_ms_p50"],
                    plan1000["reference_ms_p50"], unit="ms", ratio=plan1000["ratio_p50"]),
            verdict("Cobra s600 400 mm line planned: arrays vs per-sample loop", cobra["new_ms_p50"],
                    cobra["reference_ms_p50"], unit="ms", ratio=cobra["ratio_p50"], goal="figure <= 2 ms",
                    passed=cobra["new_ms_p50"] <= 2.0),
            verdict("largest joint difference, arrays vs loop", diff * 1e12, None, unit="1e-12 deg",
                    goal="figure <= 1000", passed=diff <= 1e-9),
            verdict("300 mm MOVES plan before its ack", line["plan_ms_p50"], joint["plan_ms_p50"], unit="ms",
                    goal="figure <= 50 ms", passed=line["plan_ms_p50"] <= 50.0),
            verdict("position query during the motion", line["query_us_p50"], joint["query_us_p50"], unit="us"),
            verdict("largest distance from the line", line["max_off_line_mm"], joint["max_off_line_mm"], unit="mm",
                    goal="figure <= 0.5 mm", passed=line["max_off_line_mm"] <= 0.5),
        ],
    }, indent=2))


if __name__ == "__main__":
    main()
