"""Pick and place, measured the paper's way: per part, the cycle time against its floor in the same run,
and 100 consecutive picks without a drop.

Runs ``aioadept pickplace``'s own run (``aioadept.cli.pickplace.run``: the sim as a process, real TCP and ZeroMQ)
on the example cell (examples/pickplace-cell.toml: a feeder queue, a 10 x 10 pallet) for ``--parts`` parts per
backend. **floor_ms** per part is the sum of the commanded motions' durations at their programmed speeds and the
hand's HAND.TIME waits (both from the server's acks) plus the locate request's time; **cycle_ms** is the client's
wall clock from the part's ``wait_sig`` to its release's ``departs`` acked. The ratio's median is the verdict
(goal <= 1.10): what the app, the wire and the client add to what the robot must take.

The locator is the app's own: the vision node's part locator on the world camera's images (its request's time is
in the floor). ``--locator truth`` answers from the world's truth on ``world.state`` instead
(aioadept.testing.world_truth: the motion sequence alone). Prints one JSON object. Usage:
``python benchmarks/bench_pickplace.py [--parts 100] [--time-scale 5] [--backends python,vplus] [--locator truth]``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import platform
import statistics
import sys
import tempfile
from pathlib import Path

from verdicts import verdict

from aioadept.apps.cell import new_run_dir
from aioadept.cell.config import CellConfig
from aioadept.apps.pickplace import PickPlaceParams
from aioadept.testing.world_truth import WorldTruthLocator

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "pickplace-cell.toml"


def run_backend(backend: str, parts: int, time_scale: float, out: Path, truth: bool) -> dict:
    from aioadept.cli.pickplace import run

    cfg = CellConfig.from_toml(EXAMPLE)
    cfg.vision.start = not truth
    cfg.robot.time_scale = time_scale
    cfg.run.out_dir = str(out)
    cfg.run.name = f"bench-{backend}"
    cfg.run.record = False
    fields = {k: getattr(cfg.pickplace, k) for k in PickPlaceParams.__dataclass_fields__}
    cfg.pickplace = PickPlaceParams(**{**fields, "parts": parts})
    if backend == "vplus":
        v = ROOT / "vplus"
        cfg.robot.sim_args = ["--vplus", str(v / "rserver.V2"), str(v / "rsskills.V2"), str(v / "rsconfig.V2"),
                              "--run", "rs.main"]
    run_dir = new_run_dir(cfg)
    with contextlib.redirect_stdout(sys.stderr):  # the app's one line; stdout carries only the JSON
        code = run(cfg, run_dir, locator=(lambda comm, c: WorldTruthLocator(c.robot.state_endpoint, c.world))
                   if truth else None)
    s = json.loads((run_dir / "summary.json").read_text()) if (run_dir / "summary.json").is_file() else {}
    ratios = [c / f for c, f in zip(s.get("cycle_ms", []), s.get("floor_ms", []), strict=True) if f > 0]
    return {
        "exit_code": code, "parts_placed": s.get("parts_placed", 0), "parts_failed": s.get("parts_failed"),
        "parts_dropped": s.get("parts_dropped"), "error": s.get("error"),
        "place_error_mm_max": max(s.get("place_error_mm") or [float("nan")]),
        "place_error_deg_max": max(s.get("place_error_deg") or [float("nan")]),
        "cycle_ms_p50": statistics.median(s["cycle_ms"]) if s.get("cycle_ms") else None,
        "floor_ms_p50": statistics.median(s["floor_ms"]) if s.get("floor_ms") else None,
        "ratio_p50": statistics.median(ratios) if ratios else None,
        "ratio_max": max(ratios) if ratios else None,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", type=int, default=100)
    ap.add_argument("--time-scale", type=float, default=5.0)
    ap.add_argument("--backends", default="python,vplus")
    ap.add_argument("--locator", choices=("vision", "truth"), default="vision")
    args = ap.parse_args()
    results, verdicts = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        for backend in args.backends.split(","):
            r = results[backend] = run_backend(backend, args.parts, args.time_scale, Path(tmp),
                                                        args.locator == "truth")
            print(f"{backend}: {json.dumps(r)}", file=sys.stderr)
            verdicts.append(verdict(f"pickplace {backend}: median cycle / floor", r["cycle_ms_p50"],
                                    r["floor_ms_p50"], unit="ms", ratio=r["ratio_p50"], goal="ratio <= 1.10",
                                    passed=r["ratio_p50"] is not None and r["ratio_p50"] <= 1.10))
            clean = r["parts_placed"] == args.parts and r["parts_dropped"] == 0
            verdicts.append(verdict(f"pickplace {backend}: {args.parts} consecutive picks, drops",
                                    r["parts_dropped"], None, unit="parts",
                                    goal=f"{args.parts} of {args.parts} placed, 0 drops", passed=clean))
    print(json.dumps({"python": platform.python_version(), "parts": args.parts, "time_scale": args.time_scale,
                      "locator": args.locator,
                      "results": results, "verdicts": verdicts}, indent=2))


if __name__ == "__main__":
    main()
