"""The verdict each benchmark puts in its JSON, for ``benchmarks/run_all.py`` (``make bench``) to tabulate.

Every ``bench_*.py`` prints one JSON object in its own shape; its top-level ``"verdicts"`` list is the standard part:
one entry per figure that has a baseline measured in the same run, and a goal where one is stated::

    {"name": "rtt p50", "figure": 61.2, "baseline": 55.0, "unit": "us", "ratio": 1.113,
     "goal": "ratio <= 1.15", "pass": true}

``goal`` is None and ``pass`` is None when no goal is stated (the table says so). ``ratio`` is figure / baseline
unless the benchmark gives its own (e.g. the median of per-round ratios, which is steadier on a loaded machine).
"""

from __future__ import annotations

import math
from typing import Any


def _num(x: float | None) -> float | None:
    if x is None or not isinstance(x, (int, float)) or not math.isfinite(x):
        return None
    return round(float(x), 3)


def verdict(name: str, figure: float | None, baseline: float | None, *, unit: str = "", ratio: float | None = None,
            goal: str | None = None, passed: bool | None = None) -> dict[str, Any]:
    """One verdict. With a ``goal``, ``passed`` says whether this run met it; without one it stays None."""
    if ratio is None and figure is not None and baseline:
        ratio = figure / baseline
    return {"name": name, "figure": _num(figure), "baseline": _num(baseline), "unit": unit, "ratio": _num(ratio),
            "goal": goal, "pass": None if goal is None else bool(passed)}
