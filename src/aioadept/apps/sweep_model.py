"""The pure parts of the focus sweep (:mod:`aioadept.apps.sweep`): where each frame was, and the fit.

- Positions: the robot state samples as a :class:`StateTrack`, the sender's clock and the vision node's mapped
  to ours within the bounds the traffic allows (:func:`clock_offset`), and without a state stream the planned
  trapezoid between the acks (:func:`profile_offset`).
- The fit: sharpness against position in, the focal plane and its uncertainty out (:func:`fit_peak`). Pure numpy
  (the focus app is in the core, without scipy): a model, a Levenberg-Marquardt least squares, and the covariance
  carried to the vertex. docs/focus.md says why this model and what it achieved.

No clock, no I/O: numbers in, numbers out.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from aioadept.geometry import Pose

FIT_LEVEL = 0.15
"""The fit uses the frames around the sharpest one down to ``min + FIT_LEVEL * (max - min)`` on both sides: most
of the peak, where the model holds, without the flat tails (measured with the virtual camera at 2.0 and 2.8 mm
between frames, 80 sweeps: levels 0.15 / 0.2 / 0.25 gave largest errors 0.06 / 0.08 / 0.12 mm; docs/focus.md)."""
MIN_FIT_POINTS = 7
"""Five parameters and at least two degrees of freedom left for the residual (the uncertainty needs them)."""


@dataclass(frozen=True, slots=True)
class PeakFit:
    """The fitted focal plane: ``peak_mm`` +- ``sigma_mm`` (standard uncertainty), from ``n_points`` frames
    between ``window_mm``; ``bracketed`` is False when the window touches an end of the data (the sharpness had
    not fallen on that side: ``side`` says which, -1 or +1); ``ok`` when a peak was found inside the window."""

    peak_mm: float
    sigma_mm: float
    n_points: int
    window_mm: tuple[float, float]
    bracketed: bool
    side: int = 0
    model: str = ""
    ok: bool = True
    why: str = ""
    params: tuple[float, ...] = ()
    """The fitted ``(a, b, z0, w, c)`` of :func:`blur_model`, for sharpness ``scale / blur_model(params, z)``."""
    scale: float = math.nan

    def summary(self) -> str:
        """One line for a log: the peak and its uncertainty, or why there is none."""
        if not self.ok:
            return f"no peak: {self.why}"
        where = "bracketed" if self.bracketed else f"not bracketed (rising at the {'far' if self.side > 0 else 'near'} end)"
        return f"peak {self.peak_mm:.2f} +- {self.sigma_mm:.3f} mm from {self.n_points} frames, {where}"

    def sharpness_at(self, z: Any) -> np.ndarray:
        """The fitted sharpness at offsets ``z`` (mm)."""
        return self.scale / blur_model(self.params, np.asarray(z, float))

    def as_dict(self) -> dict[str, Any]:
        return {"peak_mm": _finite(self.peak_mm), "sigma_mm": _finite(self.sigma_mm), "n_points": self.n_points,
                "window_mm": list(self.window_mm), "bracketed": self.bracketed, "side": self.side,
                "model": self.model, "ok": self.ok, "why": self.why, "params": list(self.params),
                "scale": _finite(self.scale)}


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def blur_model(p: Sequence[float] | np.ndarray, z: np.ndarray) -> np.ndarray:
    """The fitted curve: ``1/sharpness = a + b * sqrt((z - z0)^2 + w^2) + c * (z - z0)`` for ``p = (a, b, z0, w,
    c)``: a blur width that grows as the hypotenuse of the defocus and the in-focus blur ``w``, and a slope ``c``."""
    a, b, z0, w, c = p
    return a + b * np.sqrt((z - z0) ** 2 + w * w) + c * (z - z0)


def _vertex(p: np.ndarray) -> float:
    """Where :func:`blur_model` has its minimum (the sharpest place): ``z0 - c w / sqrt(b^2 - c^2)``; NaN when it
    has none (``|c| >= b``: the curve only rises or only falls)."""
    _a, b, z0, w, c = (float(v) for v in p)
    if not b > abs(c):
        return math.nan
    return z0 - c * abs(w) / math.sqrt(b * b - c * c)


def _jacobian(p: np.ndarray, z: np.ndarray) -> np.ndarray:
    a, b, z0, w, c = p
    d = z - z0
    r = np.sqrt(d * d + w * w)
    return np.column_stack([np.ones_like(z), r, -b * d / r - c, b * w / r, d])


def _least_squares(z: np.ndarray, y: np.ndarray, p0: Sequence[float], *, iters: int = 200) -> tuple[np.ndarray, float]:
    """Levenberg-Marquardt for :func:`blur_model` (numpy only: the focus app is in the core, without scipy).
    Returns the parameters and the residual sum of squares."""
    p = np.asarray(p0, float)
    r = blur_model(p, z) - y
    cost = float(r @ r)
    lam = 1e-3
    for _ in range(iters):
        jac = _jacobian(p, z)
        a = jac.T @ jac
        g = jac.T @ r
        improved = False
        while lam < 1e12:
            try:
                step = np.linalg.solve(a + lam * np.diag(np.diag(a) + 1e-12), -g)
            except np.linalg.LinAlgError:
                return p, cost
            q = p + step
            rq = blur_model(q, z) - y
            cq = float(rq @ rq)
            if cq < cost:
                converged = cost - cq <= 1e-12 * cost
                p, r, cost, lam, improved = q, rq, cq, max(lam / 10.0, 1e-12), True
                break
            lam *= 10.0
        if not improved or converged:
            break
    return p, cost


def fit_peak(offsets_mm: Sequence[float], sharpness: Sequence[float], *, level: float = FIT_LEVEL) -> PeakFit:
    """Fit the sharpness peak of frames at ``offsets_mm`` (any order).

    Model (:func:`blur_model`): the reciprocal sharpness as ``a + b sqrt((z - z0)^2 + w^2) + c (z - z0)``, least
    squares over the frames around the sharpest one down to :data:`FIT_LEVEL` of the peak's height; the plane is
    the model's minimum. Why: the sharpness measure falls about as the blur width grows, and a thin lens blurs a
    point into a circle whose diameter grows linearly with the defocus, combined with a fixed in-focus blur (the
    virtual camera's ``hypot(coc, floor)``): a hyperbola with a round bottom and straight flanks, which fits the
    whole top of the peak where a parabola or a Gaussian fits only its tip. The slope ``c`` takes up the skew of
    the real curve (the object's image grows by ~0.3 % per mm as it comes closer), which biases a symmetric model
    by ~0.1 mm. Uncertainty: the parameters' covariance (residual variance x (J^T J)^-1) carried to the vertex by
    its gradient, so it grows with the scatter of the frames about the curve and with too few frames near the top.
    """
    z = np.asarray(offsets_mm, float)
    s = np.asarray(sharpness, float)
    keep = np.isfinite(z) & np.isfinite(s) & (s > 0)
    z, s = z[keep], s[keep]
    order = np.argsort(z, kind="stable")
    z, s = z[order], s[order]
    n = len(z)
    if n < MIN_FIT_POINTS:
        return PeakFit(math.nan, math.inf, n, (math.nan, math.nan), False, 0, "", False,
                       f"{n} frames with a sharpness (at least {MIN_FIT_POINTS} needed)")
    i = int(np.argmax(s))
    thr = float(s.min()) + level * float(s[i] - s.min())
    a = i
    while a > 0 and s[a - 1] >= thr:
        a -= 1
    b = i
    while b < n - 1 and s[b + 1] >= thr:
        b += 1
    side = -1 if a == 0 else (1 if b == n - 1 else 0)
    bracketed = side == 0
    zz, yy = z[a:b + 1], float(s[i]) / s[a:b + 1]  # 1/s scaled to 1 at the sharpest frame
    window = (float(zz[0]), float(zz[-1]))
    model = "1/s = a + b*sqrt((z-z0)^2 + w^2) + c*(z-z0)"
    if len(zz) < MIN_FIT_POINTS:
        return PeakFit(float(z[i]), math.inf, len(zz), window, bracketed, side, model, False,
                       f"{len(zz)} frames on the peak (at least {MIN_FIT_POINTS} needed): sweep slower")
    # Start: a blur width of ~3 mm at focus, 1/s tripling 10 mm away (the virtual camera's curve, roughly).
    p, rss = _least_squares(zz, yy, [0.25, 0.25, float(z[i]), 3.0, 0.0])
    peak = _vertex(p)
    if not (math.isfinite(peak) and window[0] <= peak <= window[1]):
        return PeakFit(float(z[i]), math.inf, len(zz), window, bracketed, side, model, False,
                       "the fitted curve has no minimum inside the window")
    jac = _jacobian(p, zz)
    try:
        cov = rss / (len(zz) - 5) * np.linalg.inv(jac.T @ jac)
        grad = np.empty(5)
        for k in range(5):
            h = 1e-6 * max(1.0, abs(float(p[k])))
            q = p.copy()
            q[k] += h
            grad[k] = (_vertex(q) - peak) / h
        sigma = float(math.sqrt(max(0.0, float(grad @ cov @ grad))))
    except np.linalg.LinAlgError:
        sigma = math.inf
    if not math.isfinite(sigma):
        sigma = math.inf
    return PeakFit(float(peak), sigma, len(zz), window, bracketed, side, model, True, "",
                   tuple(float(v) for v in p), float(s[i]))


# ------------------------------------------------------------------------------------------------ positions
def axis_offset_mm(approach: Pose, pose: Pose) -> float:
    """Signed distance (mm) of ``pose`` from ``approach`` along the approach pose's tool z axis."""
    a = approach.to_matrix()
    return float(np.dot(pose.to_matrix()[:3, 3] - a[:3, 3], a[:3, 2]))


def clock_offset(lo: float, hi: float) -> float:
    """The offset (remote minus local clock, s) closest to 0 within the bounds ``[lo, hi]`` the traffic allows:
    0 when the clocks agree as far as can be measured (one machine, or NTP), else the nearer bound. With no
    consistent value (``lo > hi``: the clocks drifted during the run) the middle of the two."""
    if lo > hi:
        return (lo + hi) / 2.0
    return min(max(0.0, lo), hi)


class StateTrack:
    """Robot state samples (the sender's wall time, the local receive time, the pose's offset along the axis) and
    the position at any local time, interpolated linearly between the two samples around it.

    The sender's wall clock is mapped to ours by :func:`clock_offset` within the one bound the samples give (each
    arrived after it was taken: ``local = wall + offset`` with ``offset <= min(receive - wall)``): 0 when the
    clocks agree as far as can be measured (one machine), else that bound. Not the smallest delay itself: that
    includes the fastest transport (~0.3 ms here), which would place every frame of a 200 mm/s sweep 0.06 mm
    short; the virtual camera's follower maps the samples by the same rule.
    """

    def __init__(self) -> None:
        self.wall: list[float] = []
        self.recv: list[float] = []
        self.offset_mm: list[float] = []

    def add(self, wall_s: float, recv_s: float, offset_mm: float) -> None:
        if self.wall and wall_s <= self.wall[-1]:
            return
        self.wall.append(float(wall_s))
        self.recv.append(float(recv_s))
        self.offset_mm.append(float(offset_mm))

    def __len__(self) -> int:
        return len(self.wall)

    @property
    def delay_s(self) -> float:
        """The smallest receive time minus the sender's time seen (the fastest transport, on one clock)."""
        return min(r - w for r, w in zip(self.recv, self.wall, strict=True)) if self.wall else 0.0

    @property
    def offset_s(self) -> float:
        """Local minus sender clock (:func:`clock_offset` within ``offset <= delay_s``)."""
        return clock_offset(-math.inf, self.delay_s)

    def covers(self, t_local: float) -> bool:
        return bool(self.wall) and self.wall[-1] + self.offset_s >= t_local

    def at(self, t_local: float) -> float:
        """Offset (mm) at local epoch time ``t_local``; NaN outside the samples."""
        if not self.wall:
            return math.nan
        t = t_local - self.offset_s
        i = bisect.bisect_right(self.wall, t)
        if i == 0 or i == len(self.wall):
            return self.offset_mm[0] if i == 0 and t == self.wall[0] else math.nan
        t0, t1 = self.wall[i - 1], self.wall[i]
        a = (t - t0) / (t1 - t0)
        return self.offset_mm[i - 1] + a * (self.offset_mm[i] - self.offset_mm[i - 1])


def profile_offset(t: float, t0: float, t1: float, from_mm: float, to_mm: float, ramp_s: float) -> float:
    """Offset (mm) at time ``t`` of a trapezoidal straight line from ``from_mm`` (starting at ``t0``) to ``to_mm``
    (at rest at ``t1``) with ramps of ``ramp_s`` (clipped to half the motion): the planned profile, for a robot
    without a state stream."""
    T = t1 - t0
    if T <= 0:
        return to_mm if t >= t1 else from_mm
    ta = min(ramp_s, T / 2.0)
    tau = min(max(t - t0, 0.0), T)
    vp = 1.0 / (T - ta)
    if tau < ta:
        p = 0.5 * vp * tau * tau / ta
    elif tau <= T - ta:
        p = vp * (tau - 0.5 * ta)
    else:
        p = 1.0 - 0.5 * vp * (T - tau) ** 2 / ta
    return from_mm + p * (to_mm - from_mm)


__all__ = ["FIT_LEVEL", "MIN_FIT_POINTS", "PeakFit", "StateTrack", "axis_offset_mm", "blur_model", "clock_offset",
           "fit_peak", "profile_offset"]
