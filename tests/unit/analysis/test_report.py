"""analyze_runs / `aioadept analyze`: figures, summary.json, iterations.csv, pooling, exit codes."""

from __future__ import annotations

import csv
import json

import pytest

from aioadept.analysis import FIGURES, analyze_runs
from aioadept.cli.analyze import main
from aioadept.analysis.report import gantt_bars
from aioadept.analysis.synthetic import synthetic_recorder
from aioadept.bus import Request, Response
from aioadept.runs.capture import Recorder, load_run
from aioadept.client import MessageResult, SentMessage
from aioadept.geometry import Pose
from aioadept.protocol import Ack, Status

PNG = b"\x89PNG\r\n\x1a\n"


def _save(path, **kw):
    rec, params = synthetic_recorder(**kw)
    return rec.save(path, metadata=params)


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("runs")
    a = _save(base / "speed25" / "000", seed=1, approach_speed=25, delta_z_mm=2.0, n_steps=6)
    b = _save(base / "speed75" / "000", seed=2, approach_speed=75, delta_z_mm=1.5, n_steps=4)
    return base, a, b


def test_analyze_one_run_writes_figures_and_summary_into_the_run_dir(tmp_path) -> None:
    run_dir = _save(tmp_path / "run", seed=3, n_steps=5)
    summary = analyze_runs([run_dir])
    assert summary.out_dir == run_dir
    for name in FIGURES.values():
        data = (run_dir / name).read_bytes()
        assert data.startswith(PNG) and len(data) > 5000, name
    info = json.loads((run_dir / "summary.json").read_text())
    q = info["quantities"]
    # 5 approach steps: every quantity has 5 values except r->v (needs the previous iteration): 4
    assert q["tau_r_ms"]["stats"]["n"] == 5 and q["tau_r_to_v_ms"]["stats"]["n"] == 4
    assert q["tau_r_ms"]["fit"]["family"] == "normal" and q["tau_v_to_r_ms"]["fit"]["family"] == "lognormal"
    assert q["tau_ss_to_mrt_ms"]["equation"] == 4 and q["tau_mrt_to_b_ms"]["figure"] == "13B"
    assert set(q["tau_r_ms"]["stats"]) == {"n", "mean_ms", "std_ms", "min_ms", "median_ms", "p99_ms", "max_ms"}
    assert info["n_runs"] == 1 and info["n_complete"] == 5
    assert info["runs"][0]["parameters"]["approach_speed"] == 25
    assert info["files"]["gantt"] == FIGURES["gantt"]


def test_summary_stats_agree_with_the_iterations_written(two_runs) -> None:
    base, a, b = two_runs
    summary = analyze_runs([a, b], base / "out", plots=False)
    with (base / "out" / "iterations.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 6 + 4
    assert {r["run"] for r in rows} == {"speed25/000", "speed75/000"}  # same folder names: parent kept
    assert {(r["approach_speed"], r["delta_z_mm"]) for r in rows} == {("25", "2.0"), ("75", "1.5")}
    vals = [float(r["tau_v_to_r_ms"]) for r in rows]
    s = summary.stats["tau_v_to_r_ms"]
    assert s.n == 10 and s.mean_ms == pytest.approx(sum(vals) / 10) and s.max_ms == pytest.approx(max(vals))
    assert not (base / "out" / FIGURES["gantt"]).exists()  # plots=False
    # per cell of the parameter grid
    assert [(dict(g.parameters), g.runs, g.stats["tau_r_ms"].n) for g in summary.groups] == [
        ({"approach_speed": 25, "delta_z_mm": 2.0}, ("speed25/000",), 6),
        ({"approach_speed": 75, "delta_z_mm": 1.5}, ("speed75/000",), 4)]
    g75 = [float(r["tau_v_to_r_ms"]) for r in rows if r["run"] == "speed75/000"]
    assert summary.groups[1].stats["tau_v_to_r_ms"].mean_ms == pytest.approx(sum(g75) / 4)
    info = json.loads((base / "out" / "summary.json").read_text())
    assert info["groups"][0]["parameters"] == {"approach_speed": 25, "delta_z_mm": 2.0}


def test_gantt_window_holds_the_requests_of_the_chosen_iterations(tmp_path) -> None:
    run = load_run(_save(tmp_path / "r", seed=4, n_steps=5))
    from aioadept.analysis import iterations_of_run

    its = iterations_of_run(run)
    bars, (first, last) = gantt_bars(run, its, first=1, count=2)
    assert (first, last) == (1, 2)
    assert [b[1] for b in bars] == ["vision (i=1)", "set_speed", "move_rel_tool", "break",
                                    "vision (i=2)", "set_speed", "move_rel_tool", "break"]
    assert [b[0] for b in bars][:2] == ["vision", "robot"]
    assert bars[0][2] == its[1].t_vreq_s and bars[-1][3] == its[2].t_b_rresp_s
    bars, (first, last) = gantt_bars(run, its, first=99, count=2)  # clamped to the last iteration
    assert first == last == 4 and len(bars) == 4


def test_single_write_batches_give_zero_send_gaps_and_no_lognormal_fit(tmp_path) -> None:
    # RobotClient writes a joined batch in one write, so all three messages carry one t_send_s.
    rec = Recorder(clock=lambda: 0.0)
    pose = Pose()
    t = 1.0
    for i in range(3):
        rec.on_request(Request(f"v{i}", "VisionRequest", {}, t))
        rec.on_response(Response(f"v{i}", "VisionResponse", {"sharpness": float(i)}, t, t + 0.05))
        t += 0.051 + 0.0003 * i  # v->r: 1.0, 1.3, 1.6 ms
        for k, skill in enumerate(("set_speed", "move_rel_tool", "break")):
            mid = f"{i}{k}000000"
            args = (0.0, 0.0, 2.0, 0.0, 0.0, 0.0) if skill == "move_rel_tool" else ()
            rec.on_send(SentMessage(mid, skill, args, i + 1, t))
            done = 10.0 * i + (0.15 if skill == "break" else 0.001)
            rec.on_ack(MessageResult(mid, skill, args, i + 1, t, t + 0.155 + 0.001 * k,
                                     Ack(mid, Status.DONE, 10.0 * i, done, pose)))
        t += 0.16
    summary = analyze_runs([rec.save(tmp_path / "one_write")], plots=False)
    assert summary.stats["tau_ss_to_mrt_ms"].n == 3 and summary.stats["tau_ss_to_mrt_ms"].max_ms == 0.0
    assert summary.fits["tau_ss_to_mrt_ms"] is None and summary.fits["tau_v_to_r_ms"] is not None
    assert summary.stats["tau_v_to_r_ms"].min_ms == pytest.approx(1.0)
    assert summary.stats["tau_v_to_r_ms"].max_ms == pytest.approx(1.6)


def test_cli_pools_runs_and_reports(two_runs, tmp_path, capsys) -> None:
    base, a, b = two_runs
    out = tmp_path / "analysis"
    # a parent folder stands for the runs below it; a run named twice is analysed once
    assert main([str(base), str(a), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "τ(v→r)" in printed and "speed75/000" in printed
    info = json.loads((out / "summary.json").read_text())
    assert info["n_runs"] == 2 and info["n_complete"] == 10
    assert {r["name"] for r in info["runs"]} == {"speed25/000", "speed75/000"}
    assert all((out / name).read_bytes().startswith(PNG) for name in FIGURES.values())


def test_cli_exit_codes(tmp_path, capsys) -> None:
    assert main([str(tmp_path / "nothing")]) == 2
    assert "no run folder" in capsys.readouterr().err
    empty = Recorder(clock=lambda: 0.0).save(tmp_path / "empty")
    assert main([str(empty)]) == 1  # analysed, but no complete iteration
    info = json.loads((empty / "summary.json").read_text())
    assert info["n_complete"] == 0 and info["quantities"]["tau_r_ms"]["stats"]["n"] == 0
    with pytest.raises(SystemExit):
        main([])
