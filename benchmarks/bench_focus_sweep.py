"""Focus calibration by one sweep against the paper's stepwise loop, in the same run.

Each round runs the whole simulated cell twice, in real time with the default cell (``aioadept demo``'s: the
Python sim, the vision node with its virtual camera, focal plane ``focus_offset_mm`` ahead of the approach pose):
once ``mode = "stepwise"`` and once ``mode = "sweep"``, alternating which goes first. For each run it keeps
``search_s`` (from the first search motion's start to the focal plane known, focus.json) and the error of
``peak_offset_mm`` against the focal plane the camera was given.

Verdicts: the sweep's median ``search_s`` at most half the stepwise loop's, and the sweep's largest error at most
0.1 mm (the stepwise loop's, for scale, is what its step allows: up to ``delta_z / 2``).
Prints one JSON object. Usage: ``python benchmarks/bench_focus_sweep.py [--rounds 5] [--focus-offset-mm 20]``.
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import json
import platform
import statistics
import tempfile
from pathlib import Path

from verdicts import verdict

from aioadept.cell.config import CellConfig
from aioadept.apps.demo import run_demo


def cell(mode: str, focus_offset_mm: float, out: Path) -> CellConfig:
    cfg = CellConfig()
    cfg.robot.port = 0
    cfg.robot.state_endpoint = "tcp://127.0.0.1:0"
    cfg.vision.request_endpoint = "tcp://127.0.0.1:0"
    cfg.vision.response_endpoint = "tcp://127.0.0.1:0"
    cfg.vision.focus_offset_mm = focus_offset_mm
    cfg.focus = dataclasses.replace(cfg.focus, mode=mode)
    cfg.run.out_dir = str(out)
    cfg.run.analyze = False
    cfg.run.record = False
    return cfg


def one(mode: str, focus_offset_mm: float, out: Path) -> dict[str, float | int | str | None]:
    cfg = cell(mode, focus_offset_mm, out)
    run_dir = out / f"{mode}-{len(list(out.iterdir()))}"
    run_dir.mkdir()
    outcome = asyncio.run(run_demo(cfg, run_dir))
    r = outcome.result
    assert r is not None, outcome.error
    return {"mode": mode, "search_s": r.search_s, "peak_offset_mm": r.peak_offset_mm,
            "error_mm": abs(r.peak_offset_mm - focus_offset_mm), "peak_sigma_mm": r.peak_sigma_mm,
            "sweeps": len(r.sweep.get("plans", [])) if r.sweep else 0, "frames": len(r.frames) or len(r.sharpness),
            "pose_source": r.pose_source}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--focus-offset-mm", type=float, default=CellConfig().vision.focus_offset_mm)
    args = ap.parse_args()
    runs: dict[str, list[dict]] = {"stepwise": [], "sweep": []}
    with tempfile.TemporaryDirectory(prefix="bench-focus-sweep-") as tmp:
        out = Path(tmp)
        for i in range(args.rounds):
            for mode in (("stepwise", "sweep") if i % 2 == 0 else ("sweep", "stepwise")):
                runs[mode].append(one(mode, args.focus_offset_mm, out))
    summary = {}
    for mode, rs in runs.items():
        summary[mode] = {"search_s_p50": statistics.median(r["search_s"] for r in rs),
                         "search_s_max": max(r["search_s"] for r in rs),
                         "error_mm_max": max(r["error_mm"] for r in rs),
                         "error_mm_p50": statistics.median(r["error_mm"] for r in rs)}
    sw, st = summary["sweep"], summary["stepwise"]
    print(json.dumps({
        "python": platform.python_version(), "rounds": args.rounds, "focus_offset_mm": args.focus_offset_mm,
        "summary": summary, "runs": runs,
        "verdicts": [
            verdict("sweep search_s p50 (vs stepwise)", sw["search_s_p50"], st["search_s_p50"], unit="s",
                    goal="ratio <= 0.5", passed=sw["search_s_p50"] <= 0.5 * st["search_s_p50"]),
            verdict("largest error of the focal plane: sweep (vs stepwise)", sw["error_mm_max"],
                    st["error_mm_max"], unit="mm", goal="figure <= 0.1 mm", passed=sw["error_mm_max"] <= 0.1),
        ],
    }, indent=2))


if __name__ == "__main__":
    main()
