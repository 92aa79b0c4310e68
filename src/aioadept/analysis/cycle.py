"""The focus loop's cycle time split: ``summary.json``'s ``cycle`` (:func:`cycle_split`, medians over
consecutive complete iterations: motion, vision, the MasterControlNode's rest, and the vision part's floor) and the
one line the demo prints from it (:func:`cycle_line`).
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from itertools import pairwise
from typing import Any

from aioadept.analysis.metrics import Iteration
from aioadept.runs.capture import Run

__all__ = ["cycle_line", "cycle_split"]


def _p50(values: Sequence[float]) -> float | None:
    return float(statistics.median(values)) if values else None


def cycle_split(runs: Sequence[Run], iterations: Sequence[Iteration]) -> dict[str, Any]:
    """Medians (ms) of the focus loop's cycle and its parts, over consecutive complete iterations of each run.

    ``cycle_ms``: vision request i to vision request i+1; ``vision_ms``: request i sent to its response received;
    ``motion_ms``: the robot batch after it, first send to the last ack; ``mcn_ms``: the rest (the MasterControlNode's
    own time between them), each cycle's own rest and then their median (the median cycle minus the median motion
    and the median vision can be negative: medians do not add). ``vision_floor_ms`` = exposure + readout + graph time of the answered frames
    (``exposure_ms``, ``readout_ms``, ``proc_time_ms`` of vision.csv), each also given; ``vision_ratio`` = vision /
    its floor, ``cycle_ratio`` = cycle / (motion + vision floor) ('s goal: <= 1.10). Values are None where
    the runs hold no such data (free-running nodes do not report exposure; then the floor is the graph time alone).
    """
    cycles: list[float] = []
    visions: list[float] = []
    motions: list[float] = []
    mcns: list[float] = []
    floors: list[float] = []
    parts: dict[str, list[float]] = {"exposure_ms": [], "readout_ms": [], "graph_ms": []}
    by_run = {r.name: {v.id: v for v in r.vision} for r in runs}
    for it, nxt in pairwise(iterations):
        if not (it.complete and nxt.complete and nxt.run == it.run and nxt.index == it.index + 1):
            continue
        starts = [t for t in (it.t_ss_rreq_s, it.t_mrt_rreq_s, it.t_b_rreq_s) if t is not None]
        if None in (it.t_vreq_s, it.t_vresp_s, nxt.t_vreq_s, it.t_b_rresp_s) or not starts:
            continue
        cycles.append((nxt.t_vreq_s - it.t_vreq_s) * 1e3)
        visions.append((it.t_vresp_s - it.t_vreq_s) * 1e3)
        motions.append((it.t_b_rresp_s - min(starts)) * 1e3)
        mcns.append(cycles[-1] - visions[-1] - motions[-1])
        v = by_run.get(it.run, {}).get(it.vision_id)
        if v is not None:
            e, r, g = v.exposure_ms or 0.0, v.readout_ms or 0.0, v.proc_time_ms or 0.0
            parts["exposure_ms"].append(e)
            parts["readout_ms"].append(r)
            parts["graph_ms"].append(g)
            floors.append(e + r + g)
    cycle, vision, motion, floor = _p50(cycles), _p50(visions), _p50(motions), _p50(floors)
    out: dict[str, Any] = {
        "n_cycles": len(cycles), "cycle_ms": cycle, "motion_ms": motion, "vision_ms": vision,
        "mcn_ms": _p50(mcns),
        "vision_floor_ms": floor, **{k: _p50(v) for k, v in parts.items()},
        "vision_ratio": vision / floor if vision is not None and floor else None,
        "cycle_ratio": cycle / (motion + floor) if None not in (cycle, motion, floor) and motion + floor else None,
        "statistic": "median over cycles; floor = exposure + readout + graph",
    }
    return out


def cycle_line(cycle: Mapping[str, Any]) -> str | None:
    """One line for the terminal: the cycle split and the vision floor, or None without cycles."""
    if not cycle.get("n_cycles"):
        return None

    def f(key: str) -> str:
        v = cycle.get(key)
        return "?" if v is None else f"{v:.1f}"

    ratio = cycle.get("vision_ratio")
    cratio = cycle.get("cycle_ratio")
    return (f"cycle {f('cycle_ms')} ms = motion {f('motion_ms')} + vision {f('vision_ms')} + MCN {f('mcn_ms')} "
            f"(median of {cycle['n_cycles']}); vision floor {f('vision_floor_ms')} ms = exposure {f('exposure_ms')} "
            f"+ readout {f('readout_ms')} + graph {f('graph_ms')}"
            + (f", vision/floor {ratio:.2f}" if ratio is not None else "")
            + (f", cycle/(motion+floor) {cratio:.2f}" if cratio is not None else ""))
