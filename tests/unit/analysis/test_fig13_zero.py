"""Fig. 13 with every send gap 0.000 ms (a joined batch goes out in one write) says why on the panel."""

from __future__ import annotations

import numpy as np

from aioadept.analysis import plots


def test_a_panel_of_zeros_explains_the_one_write(tmp_path) -> None:
    fig = plots._figure(6.0, 4.0)
    ax = fig.subplots(1, 1)
    plots._lognormal_panel(ax, np.zeros(7), None, letter="A", xlabel="ms", title="set_speed -> move_rel_tool")
    text = " ".join(t.get_text().replace("\n", " ") for t in ax.texts)
    assert "all 7 values 0.000 ms: our client writes a joined batch in one write (docs/analysis.md)" in text
    path = plots.plot_lognormal_pair((np.zeros(3), None, "ms", "a"), (np.zeros(3), None, "ms", "b"),
                                     tmp_path / "fig13.png", title="t")
    assert path.stat().st_size > 0


def test_a_constant_nonzero_panel_says_there_is_no_spread() -> None:
    fig = plots._figure(6.0, 4.0)
    ax = fig.subplots(1, 1)
    plots._lognormal_panel(ax, np.full(4, 1.5), None, letter="B", xlabel="ms", title="t")
    assert any("min = max" in t.get_text() for t in ax.texts)
