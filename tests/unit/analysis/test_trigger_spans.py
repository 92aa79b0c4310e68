"""Trigger, exposure, readout and processing of each vision request: dedicated vision.csv columns (capture) and
sub-spans of the vision bars in the Gantt chart (Fig. 10), through the public functions."""

from __future__ import annotations

import csv

import pytest

from aioadept.analysis import plots
from aioadept.analysis.report import vision_spans
from aioadept.bus import Request, Response
from aioadept.runs.capture import VISION_COLUMNS, Recorder, load_run

EPOCH = 1.7e9


def _run(tmp_path):
    t = [100.0]
    rec = Recorder(clock=lambda: t[0])
    # Loop clock 100.0 <-> epoch EPOCH + 50.0: the node's epoch times map back onto the client's loop clock.
    rec.start_wall_epoch_s, rec.start_loop_s = EPOCH + 50.0, 100.0
    rec.on_request(Request("req00001", "VisionRequest", {"t_request": EPOCH + 50.010}, 100.010))
    rec.on_response(Response("req00001", "VisionResponse", {
        "sharpness": 9.5, "frame_t": EPOCH + 50.0105, "proc_time_ms": 1.25, "camera": "virtual",
        "t_trigger": EPOCH + 50.0102, "t_exposure_start": EPOCH + 50.0105, "exposure_ms": 5.0, "readout_ms": 6.3,
        "frame_seq": 17}, 100.010, 100.0240))
    rec.on_request(Request("req00002", "VisionRequest", {}, 100.3))  # free-running node of old: no timing fields
    rec.on_response(Response("req00002", "VisionResponse", {"sharpness": 1.0, "frame_t": EPOCH + 50.31},
                             100.3, 100.32))
    return rec.save(tmp_path / "run")


def test_vision_csv_has_a_column_for_each_timing_field(tmp_path):
    run_dir = _run(tmp_path)
    for col in ("t_trigger_epoch_s", "t_exposure_start_epoch_s", "exposure_ms", "readout_ms", "frame_seq"):
        assert col in VISION_COLUMNS
    with open(run_dir / "vision.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert float(rows[0]["t_trigger_epoch_s"]) == pytest.approx(EPOCH + 50.0102)
    assert float(rows[0]["exposure_ms"]) == 5.0 and float(rows[0]["readout_ms"]) == 6.3
    assert rows[0]["frame_seq"] == "17" and "exposure_ms" not in rows[0]["response_extra"]
    assert rows[1]["t_trigger_epoch_s"] == "" and rows[1]["frame_seq"] == ""
    run = load_run(run_dir)
    v = run.vision[0]
    assert (v.exposure_ms, v.readout_ms, v.frame_seq) == (5.0, 6.3, 17)
    assert v.t_exposure_start_epoch_s == pytest.approx(EPOCH + 50.0105)


def test_an_older_vision_csv_without_the_columns_still_loads(tmp_path):
    run_dir = _run(tmp_path)
    path = run_dir / "vision.csv"
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    old = VISION_COLUMNS[:VISION_COLUMNS.index("t_trigger_epoch_s")]
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, old, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    run = load_run(run_dir)
    assert run.vision[0].exposure_ms is None and run.vision[0].sharpness == 9.5


def test_vision_spans_are_trigger_exposure_readout_processing_on_the_loop_clock(tmp_path):
    run = load_run(_run(tmp_path))
    spans = {name: (a, b) for name, a, b in vision_spans(run, run.vision[0])}
    assert list(spans) == ["trigger", "exposure", "readout", "processing"]
    assert spans["trigger"] == pytest.approx((100.0102, 100.0105))
    assert spans["exposure"] == pytest.approx((100.0105, 100.0155))
    assert spans["readout"] == pytest.approx((100.0155, 100.0218))
    assert spans["processing"] == pytest.approx((100.0218, 100.02305))
    v = run.vision[0]  # every sub-span lies inside the request's send..receive bar
    assert all(v.t_send_s <= a <= b <= v.t_recv_s for a, b in spans.values())
    assert vision_spans(run, run.vision[1]) == []


def test_the_gantt_draws_the_sub_spans_with_a_legend_entry_each(tmp_path):
    run = load_run(_run(tmp_path))
    v = run.vision[0]
    bars = [("vision", "vision (i=0)", v.t_send_s, v.t_recv_s, vision_spans(run, v)),
            ("robot", "move", 100.025, 100.06)]
    from matplotlib.figure import Figure

    drawn: list[Figure] = []
    orig = plots._save
    try:
        plots._save = lambda fig, path: (drawn.append(fig), orig(fig, path))[1]
        path = plots.plot_gantt(bars, tmp_path / "g.png")
    finally:
        plots._save = orig
    assert path.read_bytes().startswith(b"\x89PNG")
    ax = drawn[0].axes[0]
    labels = [t.get_text().strip() for t in ax.get_legend().get_texts()]
    assert labels == ["vision request", "robot request", "trigger", "exposure", "readout", "processing"]
    # 2 request bars + 4 sub-spans, the sub-spans narrower and inside the vision bar's row
    rects = [p for p in ax.patches if p.get_height() in (0.6, 0.3)]
    assert sum(p.get_height() == 0.3 for p in rects) == 4
    exposure = next(p for p in rects if p.get_height() == 0.3 and p.get_facecolor()[:3] ==
                    pytest.approx(tuple(int(plots.SPAN_COLORS["exposure"][i:i + 2], 16) / 255 for i in (1, 3, 5))))
    assert exposure.get_x() == pytest.approx(0.5, abs=1e-3) and exposure.get_width() == pytest.approx(5.0, abs=1e-3)
