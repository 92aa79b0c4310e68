"""Plot functions write PNGs, including the edge cases a failed run produces."""

from __future__ import annotations

import numpy as np
import pytest

from aioadept.analysis import plots
from aioadept.analysis.fits import fit_lognormal, fit_normal

PNG = b"\x89PNG\r\n\x1a\n"


def _png(path) -> bool:
    data = path.read_bytes()
    return data.startswith(PNG) and len(data) > 3000


def test_gantt_draws_unanswered_requests_and_refuses_nothing(tmp_path) -> None:
    bars = [("vision", "vision", 1.0, 1.05), ("robot", "set_speed", 1.051, 1.052),
            ("robot", "move_rel_tool", 1.0512, 1.053), ("robot", "break", 1.0514, None)]
    assert _png(plots.plot_gantt(bars, tmp_path / "g.png"))
    with pytest.raises(ValueError):
        plots.plot_gantt([], tmp_path / "none.png")


def test_histograms_with_and_without_fits(tmp_path) -> None:
    x = np.random.default_rng(0).normal(5.2, 1.0, 200)
    assert _png(plots.plot_normal_hist(x, fit_normal(x), tmp_path / "n.png", xlabel="τ_r, ms", title="t"))
    assert _png(plots.plot_normal_hist([], None, tmp_path / "n0.png", xlabel="τ_r, ms", title="t"))
    y = np.random.default_rng(1).lognormal(0.0, 0.5, 200)
    out = plots.plot_lognormal_pair((y, fit_lognormal(y), "a, ms", "A"), (np.zeros(0), None, "b, ms", "B"),
                                    tmp_path / "sub" / "p.png", title="pair")
    assert _png(out)


def test_a_panel_without_spread_is_drawn(tmp_path) -> None:
    zeros = np.zeros(5)  # one-write batches: every send gap is 0
    assert _png(plots.plot_lognormal_pair((zeros, None, "a, ms", "A"), (zeros, None, "b, ms", "B"),
                                          tmp_path / "z.png", title="zeros"))


def test_sharpness_curve(tmp_path) -> None:
    assert _png(plots.plot_sharpness([1.0, 2.0, 4.0, 3.0], tmp_path / "s.png", delta_z_mm=2.0))
