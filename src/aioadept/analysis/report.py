"""Analyse one or many run folders: pooled metrics, fits, figures, ``summary.json`` and ``iterations.csv``.

This is what ``aioadept analyze RUN_DIR...`` runs and what the demo calls after a run::

    summary = analyze_runs(["runs/0001", "runs/0002"], "analysis")
    summary.stats["tau_r_ms"].mean_ms

Iterations are found per run (:func:`aioadept.analysis.metrics.iterations_of_run`), then pooled; each keeps its
run's name and parameters (approach speed, delta_z, ...) as columns of ``iterations.csv``.
"""

from __future__ import annotations

import csv
import json
import os
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from aioadept.analysis.cycle import cycle_split
from aioadept.analysis.fits import fit_for
from aioadept.analysis.metrics import QUANTITIES, Iteration, Stats, describe, iterations_of_run, quantity_values
from aioadept.analysis.outputs import publish, staging
from aioadept.errors import AnalysisSaveError
from aioadept.runs.capture import Run, load_run, write_atomic

__all__ = [
    "ANALYSIS_FILES", "DEFAULT_GROUP_BY", "FIGURES", "Group", "RunInfo", "Summary", "analyze_runs",
    "expand_run_dirs", "fits_table", "gantt_bars", "group_stats", "summary_table", "vision_spans",
    "write_figures"
]

FIGURES = {
    "sharpness": "fig09_sharpness.png",
    "gantt": "fig10_gantt.png",
    "tau_r": "fig11_tau_r.png",
    "overhead": "fig11b_tau_overhead.png",
    "switching_rv": "fig12_switching_robot_vision.png",
    "switching_send": "fig13_switching_sends.png",
}
"""Figure key -> file name written into the output folder."""
ITERATIONS_FILE = "iterations.csv"
SUMMARY_FILE = "summary.json"
ANALYSIS_FILES = (*FIGURES.values(), ITERATIONS_FILE, SUMMARY_FILE)
"""Every file an analysis writes into its folder; a new analysis removes those it does not write again."""

ITERATION_COLUMNS = (
    "index", "vision_id", "batch", "complete", "sharpness", "t_vreq_s", "t_vresp_s", "t_ss_rreq_s", "t_mrt_rreq_s",
    "t_b_rreq_s", "t_b_rresp_s", "t_ss_rstart_s", "t_b_rstart_s", "t_b_rdone_s",
    *(q.name for q in QUANTITIES),
)


@dataclass(frozen=True, slots=True)
class RunInfo:
    """One analysed run: where it is, its parameters, and how many iterations it gave."""

    name: str
    path: str
    parameters: Mapping[str, Any]
    n_robot: int
    n_vision: int
    n_iterations: int
    n_complete: int

    def as_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) if k != "parameters" else dict(self.parameters) for k in self.__slots__}


DEFAULT_GROUP_BY = ("approach_speed", "delta_z_mm")
"""Run parameters that split the pooled statistics into groups (the paper's experiment grid)."""


@dataclass(frozen=True, slots=True)
class Group:
    """The stats of the iterations of the runs that share ``parameters`` (e.g. one cell of the speed x dz grid)."""

    parameters: Mapping[str, Any]
    runs: tuple[str, ...]
    stats: Mapping[str, Stats]

    def as_dict(self) -> dict[str, Any]:
        return {"parameters": dict(self.parameters), "runs": list(self.runs), "n_runs": len(self.runs),
                "stats": {k: v.as_dict() for k, v in self.stats.items()}}


@dataclass(frozen=True, slots=True)
class Summary:
    """The result of :func:`analyze_runs`: per-quantity stats (ms) and fits over the pooled complete iterations."""

    runs: tuple[RunInfo, ...]
    stats: Mapping[str, Stats]
    fits: Mapping[str, Any]
    iterations: tuple[Iteration, ...]
    out_dir: Path
    files: Mapping[str, Path] = field(default_factory=dict)
    groups: tuple[Group, ...] = ()
    cycle: Mapping[str, Any] = field(default_factory=dict)
    """:func:`~aioadept.analysis.cycle.cycle_split`: the focus loop's cycle time split motion / vision / MCN, and the vision part's floor."""
    not_written: Mapping[str, str] = field(default_factory=dict)
    """Outputs of this analysis that could not be written: file name -> reason (also in ``summary.json``)."""

    @property
    def n_complete(self) -> int:
        return sum(1 for it in self.iterations if it.complete)

    def as_dict(self) -> dict[str, Any]:
        """The content of ``summary.json``."""
        from aioadept import __version__

        return {
            "aioadept_version": __version__,
            "created_utc": datetime.fromtimestamp(time.time(), tz=timezone.utc).isoformat(timespec="seconds"),
            "units": "ms",
            "n_runs": len(self.runs),
            "n_iterations": len(self.iterations),
            "n_complete": self.n_complete,
            "runs": [r.as_dict() for r in self.runs],
            "quantities": {
                q.name: {
                    "symbol": q.symbol, "label": q.label, "equation": q.equation, "figure": q.figure,
                    "fit_family": q.family,
                    "stats": self.stats[q.name].as_dict(),
                    "fit": self.fits[q.name].as_dict() if self.fits.get(q.name) is not None else None,
                }
                for q in QUANTITIES
            },
            "groups": [g.as_dict() for g in self.groups],
            "cycle": dict(self.cycle),
            "files": {k: p.name for k, p in self.files.items()},
            "not_written": dict(self.not_written),
        }


def expand_run_dirs(paths: Iterable[str | os.PathLike[str]]) -> list[Path]:
    """Run folders from the given paths: a folder with ``run.json`` is a run; a folder without one stands for the
    run folders below it (searched recursively, sorted), as an experiment writes them. Raises
    ``FileNotFoundError`` when a path holds no run."""
    out: list[Path] = []
    for p in map(Path, paths):
        if (p / "run.json").is_file():
            out.append(p)
            continue
        found = sorted(q.parent for q in p.rglob("run.json")) if p.is_dir() else []
        if not found:
            raise FileNotFoundError(f"{p}: no run folder (run.json) here or below")
        out.extend(found)
    seen: set[Path] = set()
    unique = []
    for p in out:  # a run named twice (directly and through its parent) is analysed once
        key = p.resolve()
        if key not in seen:
            seen.add(key)
            unique.append(p)
    return unique


def _names(paths: Sequence[Path]) -> list[str]:
    base = [p.name for p in paths]
    if len(set(base)) == len(base):
        return base
    # Same folder names under different parents (experiment grids): use the shortest distinguishing path.
    common = Path(os.path.commonpath([str(p.resolve()) for p in paths]))
    return [str(p.resolve().relative_to(common)) or p.name for p in paths]


def vision_spans(run: Run, v: Any) -> list[tuple[str, float, float]]:
    """A vision request's trigger, exposure, readout and processing as ``(name, start_s, end_s)`` on the client's
    loop clock (the node's epoch times shifted by run.json's ``start_wall_epoch_s - start_loop_s``; one machine, or
    clocks in step): trigger = software trigger to exposure start, exposure and readout from the node's values,
    processing = the graph's ``proc_time_ms`` right after the readout. Empty without those columns."""
    meta = run.metadata
    if v.t_exposure_start_epoch_s is None or "start_wall_epoch_s" not in meta or "start_loop_s" not in meta:
        return []
    offset = float(meta["start_wall_epoch_s"]) - float(meta["start_loop_s"])
    t_exp = v.t_exposure_start_epoch_s - offset
    spans: list[tuple[str, float, float]] = []
    if v.t_trigger_epoch_s is not None:
        spans.append(("trigger", v.t_trigger_epoch_s - offset, t_exp))
    t_exp_end = t_exp + (v.exposure_ms or 0.0) / 1e3
    spans.append(("exposure", t_exp, t_exp_end))
    t_in_memory = t_exp_end + (v.readout_ms or 0.0) / 1e3
    spans.append(("readout", t_exp_end, t_in_memory))
    if v.proc_time_ms is not None:
        spans.append(("processing", t_in_memory, t_in_memory + v.proc_time_ms / 1e3))
    return spans


def gantt_bars(run: Run, iterations: Sequence[Iteration], *, first: int = 1,
               count: int = 2) -> tuple[list[tuple[Any, ...]], tuple[int, int]]:
    """The requests of ``count`` complete iterations of ``run`` from position ``first`` (clamped to what exists),
    as ``(kind, label, t_send_s, t_recv_s)`` bars for :func:`plots.plot_gantt` (vision bars with a fifth element,
    their :func:`vision_spans`), and the iteration indices shown."""
    done = [it for it in iterations if it.complete and it.run == run.name]
    if not done:
        return [], (0, 0)
    first = max(0, min(first, len(done) - 1))
    window = done[first:first + max(1, count)]
    t0, t1 = window[0].t_vreq_s, window[-1].t_b_rresp_s
    label_of = {it.vision_id: it.index for it in window}
    bars: list[tuple[Any, ...]] = []
    for v in run.vision:
        if v.t_send_s is not None and t0 <= v.t_send_s <= t1:
            i = label_of.get(v.id)
            bars.append(("vision", f"vision (i={i})" if i is not None else "vision", v.t_send_s, v.t_recv_s,
                         vision_spans(run, v)))
    for r in run.robot:
        if r.t_send_s is not None and t0 <= r.t_send_s <= t1:
            bars.append(("robot", r.skill, r.t_send_s, r.t_recv_s))
    bars.sort(key=lambda b: b[2])
    return bars, (window[0].index, window[-1].index)


def write_figures(runs: Sequence[Run], iterations: Sequence[Iteration], stats: Mapping[str, Stats],
                  fits: Mapping[str, Any], out_dir: Path, *, gantt_first: int = 1,
                  gantt_count: int = 2, not_written: dict[str, str] | None = None) -> dict[str, Path]:
    """Write the figures that the data allows into ``out_dir``; returns figure key -> path (see FIGURES).

    Each figure is written whole or not at all. A figure that cannot be written (OSError: disk full, ...) raises,
    unless ``not_written`` is given: then its file name and the reason go there and the other figures are written.
    """
    from aioadept.analysis import plots

    files: dict[str, Path] = {}

    def attempt(key: str, make: Any) -> None:
        try:
            files[key] = make()
        except OSError as exc:
            if not_written is None:
                raise
            not_written[FIGURES[key]] = exc.strerror or str(exc)

    # Figs. 9 and 10 show one run: the first one with a complete iteration (else the first one).
    shown = next((r for r in runs if any(it.complete and it.run == r.name for it in iterations)), runs[0])
    sharp = [v.sharpness for v in shown.vision if v.sharpness is not None]
    if shown.parameters.get("mode") == "sweep":
        # A sweep's frames are not steps: they are drawn at their positions along the sweep (focus.json's
        # frames), with the fitted plane; without focus.json they cannot be placed and Fig. 9 is not drawn.
        sweep = _sweep_result(shown)
        if sweep is not None:
            attempt("sharpness", lambda: plots.plot_sweep(
                sweep, out_dir / FIGURES["sharpness"],
                title=f"Sharpness along the sweep (cf. paper Fig. 9)\nrun {shown.name}"))
    elif sharp:
        attempt("sharpness", lambda: plots.plot_sharpness(
            sharp, out_dir / FIGURES["sharpness"], delta_z_mm=_delta_z(shown.parameters),
            title=f"Sharpness after consecutive robot motions (cf. paper Fig. 9)\nrun {shown.name}"))
    bars, (a, b) = gantt_bars(shown, iterations, first=gantt_first, count=gantt_count)
    if bars:
        span = f"iteration {a}" if a == b else f"iterations {a}-{b}"
        attempt("gantt", lambda: plots.plot_gantt(
            bars, out_dir / FIGURES["gantt"],
            title=f"Vision (orange) and robot (blue) requests (cf. paper Fig. 10)\nrun {shown.name}, approach {span}"))

    def vals(name: str) -> Any:
        return quantity_values(iterations, name)

    if stats["tau_r_ms"].n:
        attempt("tau_r", lambda: plots.plot_normal_hist(
            vals("tau_r_ms"), fits.get("tau_r_ms"), out_dir / FIGURES["tau_r"],
            xlabel="τ_r, ms  (eq. 1: client wait − server time from set_speed start to break start)",
            title=f"Travel time of robot motion increments, {len(runs)} run(s) (cf. paper Fig. 11)"))
    if stats["tau_overhead_ms"].n:
        # Not a paper figure: eq. 1 contains the motion time when break's start is stamped before the motion ends
        # (the simulator, V+ forward processing); this is the part the paper's 5 ms Gaussian looks like.
        attempt("overhead", lambda: plots.plot_normal_hist(
            vals("tau_overhead_ms"), fits.get("tau_overhead_ms"), out_dir / FIGURES["overhead"],
            xlabel="τ_ovh, ms  (client wait − server time from set_speed start to break done)",
            title=f"Communication overhead of motion increments, {len(runs)} run(s)"))
    if stats["tau_r_to_v_ms"].n or stats["tau_v_to_r_ms"].n:
        attempt("switching_rv", lambda: plots.plot_lognormal_pair(
            (vals("tau_r_to_v_ms"), fits.get("tau_r_to_v_ms"), "τ(r→v), ms  (eq. 2)", "robot → vision"),
            (vals("tau_v_to_r_ms"), fits.get("tau_v_to_r_ms"), "τ(v→r), ms  (eq. 3)", "vision → robot"),
            out_dir / FIGURES["switching_rv"],
            title="Switching durations between robot and vision requests (cf. paper Fig. 12)"))
    if stats["tau_ss_to_mrt_ms"].n or stats["tau_mrt_to_b_ms"].n:
        attempt("switching_send", lambda: plots.plot_lognormal_pair(
            (vals("tau_ss_to_mrt_ms"), fits.get("tau_ss_to_mrt_ms"), "τ(ss→mrt), ms  (eq. 4)",
             "set_speed → move_rel_tool"),
            (vals("tau_mrt_to_b_ms"), fits.get("tau_mrt_to_b_ms"), "τ(mrt→b), ms  (eq. 5)",
             "move_rel_tool → break"),
            out_dir / FIGURES["switching_send"],
            title="Durations between starting consecutive sends to the RobotServer (cf. paper Fig. 13)"))
    return files


def _sweep_result(run: Run) -> dict[str, Any] | None:
    """The sweep's result from the run folder's focus.json (frames placed along the sweep), or None."""
    if run.path is None:
        return None
    try:
        result = json.loads((run.path / "focus.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(result, dict) or not any(
            isinstance(f, dict) and f.get("offset_mm") is not None for f in result.get("frames") or ()):
        return None
    return result


def _delta_z(params: Mapping[str, Any]) -> float | None:
    for key in ("delta_z_mm", "delta_z"):
        if isinstance(params.get(key), (int, float)):
            return float(params[key])
    return None


def _write_iterations(path: Path, iterations: Sequence[Iteration]) -> Path:
    param_keys = sorted({k for it in iterations for k, v in it.parameters.items()
                         if isinstance(v, (str, int, float, bool)) or v is None})
    def fill(f: Any) -> None:
        w = csv.writer(f)
        w.writerow(["run", *param_keys, *ITERATION_COLUMNS])
        for it in iterations:
            row = [it.run, *(it.parameters.get(k) for k in param_keys), *(getattr(it, c) for c in ITERATION_COLUMNS)]
            w.writerow(["" if c is None else repr(c) if isinstance(c, float) else c for c in row])

    return write_atomic(path, fill)  # a full disk leaves the previous file, never half of one


def group_stats(runs: Sequence[RunInfo], iterations: Sequence[Iteration], keys: Sequence[str]) -> tuple[Group, ...]:
    """Stats per combination of the run parameters ``keys`` (runs lacking all of them are left out), sorted."""
    by: dict[tuple, list[str]] = {}
    for r in runs:
        present = tuple((k, r.parameters[k]) for k in keys if k in r.parameters)
        if present and all(isinstance(v, (int, float, str, bool)) for _, v in present):
            by.setdefault(present, []).append(r.name)
    groups = []
    def order(combo: tuple) -> tuple:  # numbers by value, then text
        return tuple((0, float(v), "") if isinstance(v, (int, float)) else (1, 0.0, str(v)) for _, v in combo)

    for combo in sorted(by, key=order):
        names = set(by[combo])
        its = [it for it in iterations if it.run in names]
        groups.append(Group(dict(combo), tuple(by[combo]),
                            {q.name: describe(quantity_values(its, q.name)) for q in QUANTITIES}))
    return tuple(groups)


def analyze_runs(run_dirs: Iterable[str | os.PathLike[str]], out_dir: str | os.PathLike[str] | None = None, *,
                 plots: bool = True, gantt_first: int = 1, gantt_count: int = 2,
                 group_by: Sequence[str] = DEFAULT_GROUP_BY) -> Summary:
    """Load the runs, pool their approach iterations, compute stats and fits, write the outputs; return them.

    ``out_dir`` defaults to the run folder for one run and ``./analysis`` for several. Writes ``summary.json``,
    ``iterations.csv`` and (``plots=True``) the figures in :data:`FIGURES`; the Gantt chart shows ``gantt_count``
    complete iterations from position ``gantt_first`` of the first run. ``summary.json`` also holds the stats per
    combination of the run parameters named in ``group_by`` (the paper's speed x delta_z grid). Raises
    ``FileNotFoundError`` for a path with no run and ``ValueError`` for a run folder that does not parse. A run
    with no complete iteration is not an error: its stats have ``n = 0``. The outputs replace the folder's previous
    analysis as a whole (:mod:`aioadept.analysis.outputs`); those the disk could not take raise
    :class:`~aioadept.errors.AnalysisSaveError` naming them, after the others are in place.
    """
    paths = expand_run_dirs(run_dirs)
    if not paths:
        raise ValueError("run_dirs: no run folder given")
    names = _names(paths)
    runs = [_renamed(load_run(p), n) for p, n in zip(paths, names, strict=True)]
    out = Path(out_dir) if out_dir is not None else (paths[0] if len(paths) == 1 else Path("analysis"))
    out.mkdir(parents=True, exist_ok=True)

    per_run = [iterations_of_run(r) for r in runs]
    iterations = tuple(it for its in per_run for it in its)
    infos = tuple(RunInfo(r.name, str(r.path), r.parameters, len(r.robot), len(r.vision), len(its),
                          sum(1 for it in its if it.complete)) for r, its in zip(runs, per_run, strict=True))
    stats: dict[str, Stats] = {}
    fits: dict[str, Any] = {}
    for q in QUANTITIES:
        values = quantity_values(iterations, q.name)
        stats[q.name] = describe(values)
        fits[q.name] = fit_for(q.family, values)
    # One consistent analysis: every output is written into a staging folder first, then the
    # previous analysis's outputs are removed (summary.json first: no summary ever describes figures it did not
    # make) and the new ones renamed into place, summary.json last. An interruption before that leaves the previous
    # analysis as it was; a figure the data (or --no-plots) no longer gives is not left behind from an earlier run.
    with staging(out) as stage:
        not_written: dict[str, str] = {}
        staged: dict[str, Path] = {}
        if plots:
            staged.update(write_figures(runs, iterations, stats, fits, stage, gantt_first=gantt_first,
                                        gantt_count=gantt_count, not_written=not_written))
        try:
            staged["iterations"] = _write_iterations(stage / ITERATIONS_FILE, iterations)
        except OSError as exc:
            not_written[ITERATIONS_FILE] = exc.strerror or str(exc)
        files = {key: out / path.name for key, path in staged.items()}
        files["summary"] = out / SUMMARY_FILE
        summary = Summary(infos, stats, fits, iterations, out, files, group_stats(infos, iterations, group_by),
                          cycle_split(runs, iterations), not_written=dict(not_written))
        try:
            staged["summary"] = write_atomic(stage / SUMMARY_FILE,
                                             json.dumps(summary.as_dict(), indent=2, default=repr) + "\n")
        except OSError as exc:
            not_written[SUMMARY_FILE] = exc.strerror or str(exc)
            del files["summary"]
        publish(stage, out, staged, ANALYSIS_FILES, last=SUMMARY_FILE)
    if not_written:
        raise AnalysisSaveError(out, [p.name for p in files.values()], not_written, summary=summary)
    return summary


def _renamed(run: Run, name: str) -> Run:
    from dataclasses import replace

    return replace(run, metadata={**run.metadata, "name": name}) if run.name != name else run


def _fmt_ms(v: float | None) -> str:
    # About four significant digits, so the table fits an 80-column terminal from 0.05 ms to 999 ms.
    if v is None:
        return "—"
    a = abs(v)
    return f"{v:.1f}" if a >= 100 else f"{v:.2f}" if a >= 10 else f"{v:.3f}"


def summary_table(summary: Summary) -> Any:
    """A rich ``Table`` of the stats (ms): n, mean, std, min, median, p99, max per quantity."""
    from rich.table import Table

    table = Table(title=f"Approach-loop timing, ms: {summary.n_complete} iterations, {len(summary.runs)} run(s)")
    for col in ("quantity", "eq", "n", "mean", "std", "min", "median", "p99", "max"):
        table.add_column(col, justify="left" if col == "quantity" else "right", no_wrap=True)
    for q in QUANTITIES:
        s = summary.stats[q.name]
        table.add_row(q.symbol, str(q.equation or "—"), str(s.n), *(_fmt_ms(v) for v in (
            s.mean_ms, s.std_ms, s.min_ms, s.median_ms, s.p99_ms, s.max_ms)))
    return table


FAMILY_NAMES = {"normal": "Gaussian", "lognormal": "log-normal"}
"""A fit family's name (``summary.json``'s ``fit_family``) as tables and figures print it: one name per family."""


def fits_table(summary: Summary) -> Any:
    """A rich ``Table`` of the distribution fits (Gaussian for tau_r, log-normal with loc 0 for the others)."""
    from rich.table import Table

    table = Table(title="Distribution fits (maximum likelihood), ms")
    for col in ("quantity", "family", "parameters", "n"):
        table.add_column(col, justify="right" if col == "n" else "left", no_wrap=True)
    for q in QUANTITIES:
        fit = summary.fits.get(q.name)
        family = FAMILY_NAMES.get(q.family, q.family)
        if fit is None:
            table.add_row(q.symbol, family, "— (fewer than 2 distinct usable values)", str(summary.stats[q.name].n))
        elif fit.family == "normal":
            table.add_row(q.symbol, family, f"μ = {fit.mu_ms:.4g}, σ = {fit.sigma_ms:.4g}", str(fit.n))
        else:
            table.add_row(q.symbol, family, f"s = {fit.shape:.4g}, median = {fit.scale_ms:.4g}", str(fit.n))
    return table
