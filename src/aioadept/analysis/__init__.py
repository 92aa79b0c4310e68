"""The paper's timing analysis over recorded runs (Semeniuta & Falkman 2019, "Time measurements").

Where it sits: :mod:`aioadept.runs.capture` records a run folder; this package turns it into the paper's quantities
(:mod:`.metrics`, eqs. 1-5), distribution fits (:mod:`.fits`), figures like Figs. 9-13 (:mod:`.plots`, matplotlib
imported only there), the focus loop's cycle split (:mod:`.cycle`) and a summary (:mod:`.report`).
``aioadept analyze RUN_DIR...`` is :mod:`.__main__`.
"""

from aioadept.analysis.fits import LogNormalFit, NormalFit, fit_lognormal, fit_normal
from aioadept.analysis.metrics import QUANTITIES, Iteration, Stats, describe, find_iterations, iterations_of_run, \
    quantity_values
from aioadept.analysis.report import FIGURES, RunInfo, Summary, analyze_runs, summary_table

__all__ = [
    "FIGURES", "QUANTITIES", "Iteration", "LogNormalFit", "NormalFit", "RunInfo", "Stats", "Summary", "analyze_runs",
    "describe", "find_iterations", "fit_lognormal", "fit_normal", "iterations_of_run", "quantity_values",
    "summary_table",
]
