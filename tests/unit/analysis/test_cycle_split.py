"""summary.json's ``cycle``: the focus loop's cycle time split motion / vision / MCN and the vision part's floor
(exposure + readout + graph), and the line the demo prints from it."""

from __future__ import annotations

import csv
import json

import pytest

from aioadept.analysis import analyze_runs
from aioadept.analysis.metrics import Iteration
from aioadept.analysis.cycle import cycle_line, cycle_split
from aioadept.analysis.synthetic import synthetic_recorder
from aioadept.runs.capture import load_run


def _run_with_exposure(tmp_path):
    rec, params = synthetic_recorder(seed=4, n_steps=6, vision_mean_ms=30.0)
    run_dir = rec.save(tmp_path / "run", metadata=params)
    path = run_dir / "vision.csv"
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        cols, rows = reader.fieldnames, list(reader)
    for r in rows:  # what a software-triggered node reports
        r["exposure_ms"], r["readout_ms"] = "5.0", "6.3"
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, cols)
        w.writeheader()
        w.writerows(rows)
    return run_dir


def test_summary_json_splits_the_cycle_and_states_the_vision_floor(tmp_path):
    run_dir = _run_with_exposure(tmp_path)
    summary = analyze_runs([run_dir], plots=False)
    cyc = json.loads((run_dir / "summary.json").read_text())["cycle"]
    assert cyc == pytest.approx(dict(summary.cycle))
    its = [it for it in summary.iterations if it.complete]
    assert cyc["n_cycles"] == len(its) - 1 >= 4
    # the parts are medians of their own (the MCN's of each cycle's own rest), so their sum is near the cycle's
    assert cyc["motion_ms"] + cyc["vision_ms"] + cyc["mcn_ms"] == pytest.approx(cyc["cycle_ms"], rel=0.2)
    assert cyc["mcn_ms"] >= 0
    vision_ms = sorted((it.t_vresp_s - it.t_vreq_s) * 1e3 for it in its[:-1])
    assert cyc["vision_ms"] == pytest.approx(vision_ms[len(vision_ms) // 2] if len(vision_ms) % 2 else
                                             (vision_ms[len(vision_ms) // 2 - 1] + vision_ms[len(vision_ms) // 2]) / 2)
    run = load_run(run_dir)
    graph = sorted(v.proc_time_ms for v in run.vision if v.id in {it.vision_id for it in its[:-1]})
    assert cyc["exposure_ms"] == 5.0 and cyc["readout_ms"] == 6.3
    assert cyc["graph_ms"] == pytest.approx(sorted(graph)[len(graph) // 2] if len(graph) % 2 else
                                            (graph[len(graph) // 2 - 1] + graph[len(graph) // 2]) / 2)
    assert cyc["vision_floor_ms"] == pytest.approx(11.3 + cyc["graph_ms"], abs=1.0)
    assert cyc["vision_ratio"] == pytest.approx(cyc["vision_ms"] / cyc["vision_floor_ms"])
    assert cyc["cycle_ratio"] == pytest.approx(cyc["cycle_ms"] / (cyc["motion_ms"] + cyc["vision_floor_ms"]))
    line = cycle_line(cyc)
    assert line.startswith(f"cycle {cyc['cycle_ms']:.1f} ms = motion {cyc['motion_ms']:.1f} + vision ")
    assert "vision floor" in line and "exposure 5.0 + readout 6.3 + graph" in line


def test_no_cycles_no_line():
    assert cycle_line({"n_cycles": 0, "cycle_ms": None}) is None


def test_the_mcn_time_is_each_cycles_rest_never_a_difference_of_medians():
    """Three cycles (ms: vision, motion, then the MCN's rest): 60 + 30 + 10, 10 + 30 + 10, 50 + 5 + 5. The median
    cycle (60) minus the median vision (50) and motion (30) is -20 ms: the demo's line printed such a negative MCN."""
    its, t = [], 0.0
    for k, (vision, motion, rest) in enumerate([(60, 30, 10), (10, 30, 10), (50, 5, 5), (20, 20, 20)]):
        its.append(Iteration("r", k, f"v{k}", k, t, t + vision / 1e3, t_b_rreq_s=t + vision / 1e3,
                             t_b_rresp_s=t + (vision + motion) / 1e3, complete=True))
        t += (vision + motion + rest) / 1e3
    cyc = cycle_split([], its)
    assert cyc["n_cycles"] == 3 and cyc["cycle_ms"] == pytest.approx(60.0)
    assert cyc["mcn_ms"] == pytest.approx(10.0)
    assert "MCN -" not in cycle_line(cyc)
