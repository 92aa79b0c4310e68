"""The focus sweep's plan (:mod:`aioadept.apps.sweep`): how fast a sweep may go and where each one runs.

- Speed: the fastest whole program-speed percent whose travel during one exposure stays within the blur budget
  (``max_blur_fraction`` x ``depth_of_field_mm``) and ``sweep_max_speed_mm_s`` (:func:`sweep_speed`), checked before
  anything moves (:func:`check_sweep`).
- Where: the first sweep from the approach pose, then one past the open end when the peak was not bracketed, or a
  slower fine one around the fitted peak (:func:`next_plan`), never beyond :func:`max_reach_mm`. A fine sweep that
  left too few frames on the peak for the fit (a vision node slower than ``frame_interval_s``, e.g. on a loaded
  machine) is followed by a slower one, in proportion to the frames missing.

No clock, no I/O: numbers in, a :class:`SweepPlan` out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from aioadept.errors import FocusError
from aioadept.apps.sweep_model import MIN_FIT_POINTS, PeakFit

__all__ = ["SweepPlan", "check_sweep", "fine_factor", "max_reach_mm", "next_plan", "plan_sweep", "sweep_speed"]


@dataclass(frozen=True, slots=True)
class SweepPlan:
    """One straight-line sweep from ``from_mm`` to ``to_mm`` (offsets along the approach pose's tool z) at
    ``speed_pct`` (program speed), which is ``speed_mm_s`` with ``blur_mm`` of travel during one exposure."""

    from_mm: float
    to_mm: float
    speed_pct: int
    speed_mm_s: float
    blur_mm: float
    kind: str = "coarse"

    def as_dict(self) -> dict[str, Any]:
        return {"from_mm": self.from_mm, "to_mm": self.to_mm, "speed_pct": self.speed_pct,
                "speed_mm_s": self.speed_mm_s, "blur_mm": self.blur_mm, "kind": self.kind}


def sweep_speed(params: Any, exposure_ms: float, *, factor: float = 1.0, time_scale: float = 1.0) -> tuple[int, float]:
    """(program speed %, tool speed mm/s in real time) of a sweep: the fastest whole percent whose travel during
    one exposure stays within ``max_blur_fraction`` of ``depth_of_field_mm`` and below ``sweep_max_speed_mm_s``
    (times ``factor``, for the slower fine sweep). ``time_scale``: a simulated robot's speed-up (its motions run
    that many times faster than the program speed says; the blur happens in real time). ValueError, naming the
    keys, when even 1 % blurs more than allowed."""
    if not exposure_ms > 0:
        raise ValueError(f"exposure_ms = {exposure_ms!r}: a sweep needs the camera's exposure (> 0 ms)")
    v_blur = params.max_blur_fraction * params.depth_of_field_mm / (exposure_ms / 1e3)
    v = min(v_blur, params.sweep_max_speed_mm_s) * factor
    per_pct = params.line_speed_mm_s * time_scale / 100.0
    pct = min(100, math.floor(v / per_pct + 1e-9))
    if pct < 1:
        scaled = f" at time_scale {time_scale:g}" if time_scale != 1.0 else ""
        raise ValueError(
            f"max_blur_fraction = {params.max_blur_fraction:g} of depth_of_field_mm = {params.depth_of_field_mm:g} "
            f"with exposure_ms = {exposure_ms:g} allows {v:.3g} mm/s, below 1 % of line_speed_mm_s = "
            f"{params.line_speed_mm_s:g}{scaled}: shorten the exposure or use mode = \"stepwise\"")
    return pct, pct * per_pct


def plan_sweep(params: Any, exposure_ms: float, from_mm: float, to_mm: float, *, kind: str = "coarse",
               factor: float = 1.0, time_scale: float = 1.0) -> SweepPlan:
    """The :class:`SweepPlan` from ``from_mm`` to ``to_mm`` (see :func:`sweep_speed`)."""
    pct, v = sweep_speed(params, exposure_ms, factor=factor, time_scale=time_scale)
    return SweepPlan(float(from_mm), float(to_mm), pct, v, v * exposure_ms / 1e3, kind)


def check_sweep(params: Any, exposure_ms: float, time_scale: float = 1.0) -> None:
    """ValueError (one line, naming the keys) unless a sweep with these values can run: called before anything
    starts, so ``--mode sweep`` with an exposure too long for the blur budget exits 2 with nothing moved."""
    if params.mode == "sweep":
        sweep_speed(params, exposure_ms, time_scale=time_scale)
        sweep_speed(params, exposure_ms, factor=params.fine_speed_factor, time_scale=time_scale)


def max_reach_mm(params: Any) -> float:
    """How far from the approach pose a sweep may take the tool, either way along z: ``max_steps x delta_z_mm``,
    the reach the stepwise loop is allowed (80 mm by default), so choosing the sweep never takes the object nearer
    the camera than the cell already accepts."""
    return float(params.max_steps * params.delta_z_mm)


def next_plan(params: Any, exposure_ms: float, fit: PeakFit, here_mm: float, time_scale: float, *,
              forward_only: bool = False, last: SweepPlan | None = None) -> SweepPlan:
    """After a sweep ending at ``here_mm`` (``last``, when known): extend past the end where the peak was not
    bracketed (or nothing was fitted), else a slower sweep over ``fine_range_mm`` around the fitted peak, run from
    the side the robot is on through the whole window (see :func:`fine_factor` for its speed)."""
    if not fit.bracketed or not math.isfinite(fit.peak_mm):
        ext = params.sweep_range_mm / 2.0
        reach = max_reach_mm(params)
        if fit.side < 0:  # still rising at the near end: the plane is behind the start
            lo = min(fit.window_mm[0], here_mm) if math.isfinite(fit.window_mm[0]) else here_mm
            to = max(lo - ext, -reach)
        else:
            hi = max(fit.window_mm[1], here_mm) if math.isfinite(fit.window_mm[1]) else here_mm
            to = min(hi + ext, reach)
        if abs(to - here_mm) < 1.0:
            raise FocusError(f"no sharpness peak within {reach:g} mm of the approach pose (max_steps x delta_z_mm, "
                             "the stepwise loop's reach too)")
        return plan_sweep(params, exposure_ms, here_mm, to, kind="extend", time_scale=time_scale)
    half = params.fine_range_mm / 2.0
    centre = fit.peak_mm
    a, b = (centre + half, centre - half) if here_mm >= centre else (centre - half, centre + half)
    if forward_only:  # placed by the profile: a time offset shifts a sweep along its direction; keep one direction
        a, b = centre - half, centre + half
    reach = max_reach_mm(params)
    a, b = min(max(a, -reach), reach), min(max(b, -reach), reach)
    return plan_sweep(params, exposure_ms, a, b, kind="fine",
                      factor=fine_factor(params, exposure_ms, fit, last, time_scale), time_scale=time_scale)


def fine_factor(params: Any, exposure_ms: float, fit: PeakFit, last: SweepPlan | None, time_scale: float) -> float:
    """The fine sweep's speed, as a factor of the fastest (:func:`sweep_speed`): ``fine_speed_factor``; after a fine
    sweep whose frames left fewer than the fit needs on the peak, that sweep's speed times the share of frames
    there were (``n_points / (MIN_FIT_POINTS + 1)``, at least a quarter), never below 1 % program speed. The frames
    of every sweep count in the next fit, so a slower sweep over the same window adds more of them."""
    factor = params.fine_speed_factor
    if last is None or last.kind != "fine" or fit.n_points >= MIN_FIT_POINTS:
        return factor
    _, fastest = sweep_speed(params, exposure_ms, time_scale=time_scale)
    slowest = params.line_speed_mm_s * time_scale / 100.0  # 1 % program speed
    share = max(0.25, fit.n_points / (MIN_FIT_POINTS + 1))
    return max(last.speed_mm_s * share, slowest) / fastest
