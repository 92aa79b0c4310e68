"""Part locator benchmark: the locate graph per frame against the same functions called directly, and its accuracy
on synthetic views with known truth. Prints one JSON object.

1. ``graph``: ``locate_graph`` (markers + colours) per 1024 x 768 synthetic frame of the world camera's model
   (``aioadept.vision.synthetic``: six 15 mm marked parts and two coloured boxes at random poses, blur and sensor
   noise), median and p99. Baseline: the same five step functions called directly in a row, so the ratio is what
   the CompGraph costs. Informative target: median <= 20 ms (a locate answer well inside one pick cycle).
2. ``accuracy``: over the same frames (parts placed apart, as on a table), the worst and median position (mm) and
   yaw (deg) error of every part found, and how many were missed or found in excess. Goal: <= 1 mm and <= 1 deg.

Usage: ``python benchmarks/bench_locate.py [--frames 60] [--seed 1]``.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time

import numpy as np

from verdicts import verdict


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()

    from aioadept.vision.calibration import CameraCalibration
    from aioadept.vision import locate as L
    from aioadept.vision.synthetic import SyntheticPart, render

    cal = CameraCalibration()
    hyper = dict(L.DEFAULT_HYPERPARAMETERS, height_mm=20.0, colours=("green", "blue"))
    graph = L.locate_graph(cal, **hyper)
    rng = np.random.default_rng(args.seed)
    frames = []
    for k in range(args.frames):
        # Parts placed apart (centres >= 65 mm: no two touch), as on a table; the world has no collisions, and an
        # overlapped part is a different question (a hidden marker is not found, a hidden blob is cut).
        centres: list[tuple[float, float]] = []
        while len(centres) < 8:
            c = (float(rng.uniform(300, 600)), float(rng.uniform(-130, 130)))
            if all(math.hypot(c[0] - a, c[1] - b) >= 65.0 for a, b in centres):
                centres.append(c)
        parts = [SyntheticPart(*centres[i], float(rng.uniform(-180, 180)), (40.0, 40.0, 20.0), marker=i)
                 for i in range(6)]
        parts += [SyntheticPart(*centres[6 + j], float(rng.uniform(-180, 180)), (50.0, 30.0, 20.0), rgb)
                  for j, rgb in enumerate(((40, 160, 60), (40, 70, 200)))]
        frames.append((render(cal, parts, seed=k), parts))

    def direct(img: np.ndarray) -> tuple:
        markers = L.detect_markers(img, hyper["dictionary"])
        found_m = L.marker_parts(markers, cal, hyper["marker_mm"], hyper["height_mm"])
        masks = L.segment_colours(img, hyper["colours"], hyper["colour_tol"])
        found_c = L.colour_parts(masks, cal, hyper["height_mm"], hyper["min_area_mm2"], hyper["min_width_mm"],
                                 hyper["min_fill"])
        return L.merge_parts(found_m, found_c)

    graph_ms, direct_ms = [], []
    pos, yaw, missed, extra = [], [], 0, 0
    for img, truth in frames:  # alternate, so machine load hits both alike
        t0 = time.perf_counter()
        res = L.locate(img, graph)
        graph_ms.append((time.perf_counter() - t0) * 1e3)
        t0 = time.perf_counter()
        direct(img)
        direct_ms.append((time.perf_counter() - t0) * 1e3)
        for t in truth:
            cands = [p for p in res.parts if (p.marker == t.marker if t.marker is not None else
                                              p.kind == "colour" and p.colour == ("green" if t.rgb[1] == 160 else
                                                                                   "blue"))]
            if not cands:
                missed += 1
                continue
            p = min(cands, key=lambda p: math.hypot(p.x_mm - t.x_mm, p.y_mm - t.y_mm))
            d = math.hypot(p.x_mm - t.x_mm, p.y_mm - t.y_mm)
            if d > 10:  # another blob of that colour: not this part
                missed += 1
                continue
            period = 360.0 if t.marker is not None else 180.0
            pos.append(d)
            yaw.append(abs((p.yaw_deg - t.yaw_deg + period / 2) % period - period / 2))
        extra += max(0, len(res.parts) - len(truth))

    def stats(v: list[float]) -> dict:
        s = sorted(v)
        return {"median_ms": statistics.median(s), "p99_ms": s[min(len(s) - 1, int(0.99 * len(s)))]}

    g, d = stats(graph_ms), stats(direct_ms)
    acc = {"parts": len(pos), "missed": missed, "extra": extra, "pos_max_mm": max(pos), "pos_median_mm":
           statistics.median(pos), "yaw_max_deg": max(yaw), "yaw_median_deg": statistics.median(yaw)}
    out = {"frames": args.frames, "graph": g, "direct": d, "accuracy": acc}
    out["verdicts"] = [
        verdict("locate graph per frame, median, vs the same calls direct", g["median_ms"], d["median_ms"],
                unit="ms", goal="median <= 20 ms", passed=g["median_ms"] <= 20.0),
        verdict("locate: worst position error (synthetic views)", acc["pos_max_mm"], None, unit="mm",
                goal="<= 1 mm", passed=acc["pos_max_mm"] <= 1.0),
        verdict("locate: worst yaw error (synthetic views)", acc["yaw_max_deg"], None, unit="deg",
                goal="<= 1 deg", passed=acc["yaw_max_deg"] <= 1.0),
    ]
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
