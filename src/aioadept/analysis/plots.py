"""Figures like the paper's Figs. 9-13, written as PNG files.

- :func:`plot_sharpness`  Fig. 9: sharpness after each motion increment, red line at the maximum;
- :func:`plot_gantt`      Fig. 10: vision (orange) and robot (blue) requests as bars from send to receive, each vision
  request with its trigger, exposure, readout and processing drawn inside it as sub-spans;
- :func:`plot_normal_hist` Fig. 11: histogram of tau_r with the fitted Gaussian PDF;
- :func:`plot_lognormal_pair` Figs. 12 and 13: two histograms (A, B) with fitted log-normal PDFs and min/max lines.

matplotlib is imported inside the functions and only through its object API (``Figure`` + Agg canvas), so
importing this module is cheap and no pyplot global state or GUI backend is involved.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["DPI", "ROBOT_COLOR", "VISION_COLOR", "plot_gantt", "plot_lognormal_pair", "plot_normal_hist",
           "plot_sharpness"]

DPI = 110
VISION_COLOR = "#f28e2b"  # orange, as the paper's vision requests
ROBOT_COLOR = "#4e79a7"   # blue, as the paper's robot requests
HIST_COLOR = "#a0c4e8"
FIT_COLOR = "#1f3b73"
MINMAX_COLOR = "#c0392b"
SPAN_COLORS = {"trigger": "#7f7f7f", "exposure": "#edc948", "readout": "#b07aa1", "processing": "#59a14f"}
"""Sub-spans of a vision request in Fig. 10: trigger latency, exposure, readout + transfer, graph processing."""


def _figure(width_in: float, height_in: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Any, path: str | os.PathLike[str]) -> Path:
    from aioadept.runs.capture import write_atomic

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    # Whole or not at all (a full disk must not leave an empty fig09_sharpness.png): a temporary file, then rename.
    return write_atomic(out, lambda f: fig.savefig(f, dpi=DPI, format=out.suffix.lstrip(".") or "png"), binary=True)


def _bins(x: np.ndarray) -> int:
    # Freedman-Diaconis (robust to the heavy tails of the switching durations), bounded so small samples still
    # show a shape and big ones are not noisy.
    try:
        fd = len(np.histogram_bin_edges(x, bins="fd")) - 1
    except (ValueError, MemoryError):
        fd = 0
    return int(min(60, max(6, fd, math.ceil(2 * x.size ** (1 / 3)))))


def plot_sharpness(sharpness: Sequence[float], path: str | os.PathLike[str], *, title: str | None = None,
                   delta_z_mm: float | None = None) -> Path:
    """Fig. 9: sharpness per step (step 0 = the approach pose), red vertical line at the maximum."""
    s = np.asarray([v for v in sharpness if v is not None], dtype=float)
    fig = _figure(6.4, 3.8)
    ax = fig.add_subplot()
    steps = np.arange(s.size)
    ax.plot(steps, s, "o-", color="#333333", markersize=4, linewidth=1.2, label="sharpness")
    if s.size:
        k = int(np.argmax(s))
        ax.axvline(k, color="red", linewidth=1.5, label=f"maximum (step {k})")
    xlabel = "step (motion increments from the approach pose)"
    if delta_z_mm is not None:
        xlabel += f", Δz = {delta_z_mm:g} mm"
    ax.set_xlabel(xlabel)
    ax.set_ylabel("sharpness (std of Sobel-x profile)")
    ax.set_title(title or "Sharpness after consecutive robot motions (cf. paper Fig. 9)")
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    return _save(fig, path)


def plot_sweep(result: Mapping[str, Any], path: str | os.PathLike[str], *, title: str | None = None) -> Path:
    """The focus sweep: each frame's sharpness against its position along tool z (one colour per
    sweep), the fitted curve over its window, and the fitted plane with its +-1 sigma band."""
    from aioadept.apps.sweep_model import blur_model

    fig = _figure(6.4, 3.8)
    ax = fig.add_subplot()
    frames = [f for f in result.get("frames") or () if f.get("offset_mm") is not None]
    plans = (result.get("sweep") or {}).get("plans") or []
    for k in sorted({int(f.get("sweep", 0)) for f in frames}):
        mine = [f for f in frames if int(f.get("sweep", 0)) == k]
        kind = plans[k]["kind"] if k < len(plans) else "sweep"
        speed = f", {plans[k]['speed_mm_s']:g} mm/s" if k < len(plans) else ""
        ax.plot([f["offset_mm"] for f in mine], [f["sharpness"] for f in mine], "o", markersize=4,
                label=f"frames, sweep {k} ({kind}{speed})")
    fits = (result.get("sweep") or {}).get("fits") or []
    fit = fits[-1] if fits else {}
    if fit.get("ok") and fit.get("params") and fit.get("scale"):
        z = np.linspace(fit["window_mm"][0], fit["window_mm"][1], 200)
        ax.plot(z, fit["scale"] / blur_model(fit["params"], z), "-", color="#333333", linewidth=1.2,
                label="fit: 1/s = a + b√((z−z0)² + w²) + c(z−z0)")
    peak, sigma = result.get("peak_offset_mm"), result.get("peak_sigma_mm")
    if isinstance(peak, (int, float)):
        ax.axvline(peak, color="red", linewidth=1.5,
                   label=f"focal plane {peak:.3f} mm" + (f" ± {sigma:.3f}" if isinstance(sigma, (int, float)) else ""))
        if isinstance(sigma, (int, float)) and math.isfinite(sigma):
            ax.axvspan(peak - sigma, peak + sigma, color="red", alpha=0.15)
    source = result.get("pose_source") or "?"
    ax.set_xlabel(f"position along tool z from the approach pose, mm (pose from the {source})")
    ax.set_ylabel("sharpness (std of Sobel-x profile)")
    ax.set_title(title or "Sharpness along one sweep, with the fit")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return _save(fig, path)


def plot_gantt(bars: Sequence[tuple[Any, ...]], path: str | os.PathLike[str], *,
               title: str | None = None) -> Path:
    """Fig. 10: one row per request, a bar from send to receive (ms from the first send).

    ``bars`` are ``(kind, label, t_send_s, t_recv_s)`` in send order, ``kind`` "vision" or "robot"; a request
    never answered (``t_recv_s`` None) is drawn hatched to the end of the window. A fifth element, a sequence of
    ``(name, start_s, end_s)`` on the same clock, draws those sub-spans as narrow bars inside the request's bar
    (names from :data:`SPAN_COLORS`: trigger, exposure, readout, processing), with a legend entry each.
    """
    if not bars:
        raise ValueError("bars: nothing to draw")
    t0 = min(b[2] for b in bars)
    t_end = max((b[3] if b[3] is not None else b[2]) for b in bars)
    n = len(bars)
    fig = _figure(9.0, max(2.6, 0.36 * n + 1.4))
    ax = fig.add_subplot()
    spans_seen: list[str] = []
    for row, bar in enumerate(bars):
        kind, _label, ts, tr = bar[:4]
        color = VISION_COLOR if kind == "vision" else ROBOT_COLOR
        start = (ts - t0) * 1000.0
        end = ((tr if tr is not None else t_end) - t0) * 1000.0
        # A bar shorter than a pixel still shows as a tick: the send-to-send gaps are ~0.2 ms in a ~300 ms window.
        width = max(end - start, (t_end - t0) * 1000.0 * 0.002)
        ax.barh(row, width, left=start, height=0.6, color=color, edgecolor=color if tr is not None else "black",
                hatch=None if tr is not None else "//", linewidth=0.8)
        for name, s0, s1 in (bar[4] if len(bar) > 4 and bar[4] else ()):
            if s1 < s0:
                continue
            ax.barh(row, max((s1 - s0) * 1000.0, (t_end - t0) * 1000.0 * 0.002), left=(s0 - t0) * 1000.0,
                    height=0.3, color=SPAN_COLORS.get(name, "black"), linewidth=0)
            if name not in spans_seen:
                spans_seen.append(name)
    ax.set_yticks(range(n), [b[1] for b in bars], fontsize=9)
    ax.invert_yaxis()  # first request on top, time flows down and right like the paper's chart
    ax.set_xlabel("time since the first request in the window, ms (client loop clock)")
    ax.set_xlim(left=-(t_end - t0) * 1000.0 * 0.01)
    ax.grid(axis="x", alpha=0.3)
    from matplotlib.patches import Patch

    ax.legend(handles=[Patch(color=VISION_COLOR, label="vision request"),
                       Patch(color=ROBOT_COLOR, label="robot request"),
                       *(Patch(color=SPAN_COLORS.get(n, "black"), label=f"  {n}") for n in spans_seen)],
              loc="upper right", fontsize=9)
    ax.set_title(title or "Vision (orange) and robot (blue) requests in the approach loop (cf. paper Fig. 10)")
    return _save(fig, path)


def plot_normal_hist(values_ms: Sequence[float] | np.ndarray, fit: Any, path: str | os.PathLike[str], *,
                     xlabel: str, title: str) -> Path:
    """Fig. 11: density histogram of ``values_ms`` with the fitted Gaussian PDF (``fit`` may be None)."""
    x = np.asarray(values_ms, dtype=float)
    fig = _figure(6.4, 4.0)
    ax = fig.add_subplot()
    if x.size:
        ax.hist(x, bins=_bins(x), density=True, color=HIST_COLOR, edgecolor="white", label=f"measured (n={x.size})")
    if fit is not None:
        pad = 4 * fit.sigma_ms
        grid = np.linspace(min(x.min(), fit.mu_ms - pad), max(x.max(), fit.mu_ms + pad), 400)
        ax.plot(grid, fit.pdf(grid), color=FIT_COLOR, linewidth=2,
                label=f"Gaussian fit: μ = {fit.mu_ms:.3f} ms, σ = {fit.sigma_ms:.3f} ms")
    if not x.size:
        ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center", va="center", color="gray")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("probability density, 1/ms")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if x.size:
        ax.set_ylim(top=ax.get_ylim()[1] * 1.3)  # headroom, so the legend does not cover the bars
        ax.legend(loc="upper right", fontsize=9)
    return _save(fig, path)


def _lognormal_panel(ax: Any, x: np.ndarray, fit: Any, *, letter: str, xlabel: str, title: str) -> None:
    if x.size and np.ptp(x) == 0:
        # No spread (e.g. a batch written in one write: every send gap is 0): a histogram would be one
        # meaningless block, so say what the values are instead.
        ax.axvline(x[0], color=MINMAX_COLOR, linestyle="--", linewidth=1.2)
        why = ("our client writes a joined batch in one write\n(docs/analysis.md)" if x[0] == 0
               else "min = max, no distribution to fit")
        ax.text(0.5, 0.5, f"all {x.size} values {x[0]:.3f} ms:\n{why}",
                transform=ax.transAxes, ha="center", va="center", color="#333333",
                bbox={"facecolor": "white", "edgecolor": "#cccccc"})
        ax.set_xlim(x[0] - 1.0, x[0] + 1.0)
        ax.set_yticks([])
        ax.set_xlabel(xlabel)
        ax.set_title(f"({letter}) {title}", loc="left")
        return
    if x.size:
        ax.hist(x, bins=_bins(x), density=True, color=HIST_COLOR, edgecolor="white", label=f"measured (n={x.size})")
        for v, name, dx, ha in ((x.min(), "min", 3, "left"), (x.max(), "max", -3, "right")):
            ax.axvline(v, color=MINMAX_COLOR, linestyle="--", linewidth=1.2)
            # Labels inside the lines, so the max label is never cut at the right edge.
            ax.annotate(f"{name} {v:.3f} ms", (v, 1.0), xycoords=("data", "axes fraction"), xytext=(dx, -12),
                        textcoords="offset points", fontsize=8, color=MINMAX_COLOR, ha=ha)
    if fit is not None and x.size:
        grid = np.linspace(max(x.min() * 0.5, 1e-6), x.max() * 1.05, 400)
        ax.plot(grid, fit.pdf(grid), color=FIT_COLOR, linewidth=2,
                label=f"log-normal fit: s = {fit.shape:.3f}, median = {fit.scale_ms:.3f} ms")
    elif not x.size:
        ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center", va="center", color="gray")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("probability density, 1/ms")
    ax.set_title(f"({letter}) {title}", loc="left")
    ax.grid(alpha=0.3)
    if x.size:
        # Headroom above the bars; the legend sits below the min/max labels, over the thin tail.
        ax.set_ylim(top=ax.get_ylim()[1] * 1.3)
        ax.legend(loc="upper right", bbox_to_anchor=(1.0, 0.92), fontsize=8)


def plot_lognormal_pair(a: tuple[np.ndarray, Any, str, str], b: tuple[np.ndarray, Any, str, str],
                        path: str | os.PathLike[str], *, title: str) -> Path:
    """Figs. 12/13: panels (A) and (B), each ``(values_ms, fit or None, xlabel, panel title)``."""
    fig = _figure(11.0, 4.0)
    axes = fig.subplots(1, 2)
    for ax, letter, (x, fit, xlabel, panel) in zip(axes, "AB", (a, b), strict=True):
        _lognormal_panel(ax, np.asarray(x, dtype=float), fit, letter=letter, xlabel=xlabel, title=panel)
    fig.suptitle(title)
    return _save(fig, path)
