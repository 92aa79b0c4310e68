"""Distribution fits of the timing metrics, as in the paper: Gaussian for tau_r (Fig. 11), log-normal for the
switching durations (Figs. 12, 13).

Pure functions over arrays of milliseconds; scipy's maximum-likelihood fits. The log-normal is fitted with the
location fixed at 0 (``scipy.stats.lognorm.fit(x, floc=0)``), so ``scale_ms`` is the median and ``ln(scale_ms)``
and ``shape`` are the mean and std of ``ln(x)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["LogNormalFit", "NormalFit", "fit_for", "fit_lognormal", "fit_normal"]


@dataclass(frozen=True, slots=True)
class NormalFit:
    """Gaussian N(mu, sigma²) fitted by maximum likelihood (sigma is the ddof=0 std), over ``n`` samples."""

    mu_ms: float
    sigma_ms: float
    n: int
    min_ms: float
    max_ms: float
    family: str = "normal"

    def pdf(self, x_ms: Any) -> np.ndarray:
        from scipy import stats

        return stats.norm.pdf(np.asarray(x_ms, dtype=float), loc=self.mu_ms, scale=self.sigma_ms)

    def as_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__slots__}


@dataclass(frozen=True, slots=True)
class LogNormalFit:
    """Log-normal with loc 0: ``ln(x) ~ N(ln(scale_ms), shape²)``, fitted over ``n`` positive samples.

    ``n_excluded`` counts samples <= 0 (equal timestamps at the clock's resolution), which a log-normal cannot
    take; ``min_ms``/``max_ms`` are over all samples.
    """

    shape: float
    scale_ms: float
    n: int
    min_ms: float
    max_ms: float
    n_excluded: int = 0
    family: str = "lognormal"

    @property
    def mu_log(self) -> float:
        """Mean of ln(x / 1 ms)."""
        return math.log(self.scale_ms)

    @property
    def median_ms(self) -> float:
        return self.scale_ms

    @property
    def mean_ms(self) -> float:
        return self.scale_ms * math.exp(self.shape**2 / 2)

    @property
    def mode_ms(self) -> float:
        return self.scale_ms * math.exp(-self.shape**2)

    def pdf(self, x_ms: Any) -> np.ndarray:
        from scipy import stats

        return stats.lognorm.pdf(np.asarray(x_ms, dtype=float), self.shape, loc=0.0, scale=self.scale_ms)

    def as_dict(self) -> dict[str, Any]:
        d = {k: getattr(self, k) for k in self.__slots__}
        d.update(mu_log=self.mu_log, median_ms=self.median_ms, mean_ms=self.mean_ms, mode_ms=self.mode_ms)
        return d


def fit_normal(samples_ms: Sequence[float] | np.ndarray) -> NormalFit | None:
    """Gaussian MLE fit; None with fewer than 2 samples or no spread (a fit would be degenerate)."""
    from scipy import stats

    x = np.asarray(samples_ms, dtype=float)
    x = x[np.isfinite(x)]
    if x.size < 2 or np.ptp(x) == 0:
        return None
    mu, sigma = stats.norm.fit(x)
    return NormalFit(float(mu), float(sigma), int(x.size), float(x.min()), float(x.max()))


def fit_lognormal(samples_ms: Sequence[float] | np.ndarray) -> LogNormalFit | None:
    """Log-normal MLE fit with ``floc=0`` over the positive samples; None with fewer than 2 distinct of them."""
    from scipy import stats

    x = np.asarray(samples_ms, dtype=float)
    x = x[np.isfinite(x)]
    pos = x[x > 0]
    if pos.size < 2 or np.ptp(pos) == 0:
        return None
    shape, _, scale = stats.lognorm.fit(pos, floc=0)
    return LogNormalFit(float(shape), float(scale), int(pos.size), float(x.min()), float(x.max()),
                        int(x.size - pos.size))


def fit_for(family: str, samples_ms: Sequence[float] | np.ndarray) -> NormalFit | LogNormalFit | None:
    """The fit of ``family`` ("normal" or "lognormal"); raises ``ValueError`` for another name."""
    if family == "normal":
        return fit_normal(samples_ms)
    if family == "lognormal":
        return fit_lognormal(samples_ms)
    raise ValueError(f"family: {family!r} is not 'normal' or 'lognormal'")
