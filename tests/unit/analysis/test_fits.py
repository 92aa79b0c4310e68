"""Distribution fits recover known parameters from seeded samples and refuse degenerate input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aioadept.analysis.fits import fit_for, fit_lognormal, fit_normal


def test_normal_fit_recovers_mu_and_sigma() -> None:
    x = np.random.default_rng(7).normal(5.219, 0.964, 5000)  # the paper's Fig. 11 values
    fit = fit_normal(x)
    assert fit is not None and fit.n == 5000
    assert fit.mu_ms == pytest.approx(5.219, abs=0.05)
    assert fit.sigma_ms == pytest.approx(0.964, rel=0.04)
    assert (fit.min_ms, fit.max_ms) == (x.min(), x.max())
    grid = np.linspace(0, 10, 2001)
    assert np.trapezoid(fit.pdf(grid), grid) == pytest.approx(1.0, abs=1e-3)


def test_lognormal_fit_recovers_shape_and_scale() -> None:
    rng = np.random.default_rng(11)
    x = 0.9 * np.exp(0.6 * rng.standard_normal(5000))
    fit = fit_lognormal(x)
    assert fit is not None and fit.n == 5000 and fit.n_excluded == 0
    assert fit.shape == pytest.approx(0.6, rel=0.04)
    assert fit.scale_ms == pytest.approx(0.9, rel=0.04)
    assert fit.mu_log == pytest.approx(math.log(fit.scale_ms))
    assert fit.mean_ms == pytest.approx(fit.scale_ms * math.exp(fit.shape**2 / 2))
    d = fit.as_dict()
    assert d["family"] == "lognormal" and d["median_ms"] == fit.scale_ms


def test_lognormal_fit_excludes_non_positive_samples_but_reports_them() -> None:
    fit = fit_lognormal([0.0, 0.0, 1.0, 2.0, 4.0])
    assert fit is not None and (fit.n, fit.n_excluded, fit.min_ms, fit.max_ms) == (3, 2, 0.0, 4.0)
    # MLE with loc 0: scale = geometric mean, shape = population std of ln(x)
    logs = np.log([1.0, 2.0, 4.0])
    assert fit.scale_ms == pytest.approx(math.exp(logs.mean()), rel=1e-4)
    assert fit.shape == pytest.approx(logs.std(), rel=1e-4)


@pytest.mark.parametrize("values", [[], [1.0], [0.0, 0.0, 0.0], [2.0, 2.0]])
def test_degenerate_samples_give_no_fit(values) -> None:
    assert fit_lognormal(values) is None
    assert fit_normal(values) is None


def test_fit_for_dispatches_on_family() -> None:
    assert fit_for("normal", [1.0, 2.0, 3.0]).family == "normal"
    assert fit_for("lognormal", [1.0, 2.0, 3.0]).family == "lognormal"
    with pytest.raises(ValueError):
        fit_for("weibull", [1.0, 2.0])
