"""The fits table names each distribution family once, in one spelling: a quantity without a
fit said ``lognormal`` beside rows that said ``log-normal``."""

from __future__ import annotations

from aioadept.analysis import analyze_runs
from aioadept.analysis.report import FAMILY_NAMES, fits_table
from aioadept.analysis.metrics import QUANTITIES
from aioadept.bus import Request, Response
from aioadept.runs.capture import Recorder
from aioadept.client import MessageResult, SentMessage
from aioadept.geometry import Pose
from aioadept.protocol import Ack, Status


def _one_write_run(tmp_path):
    """Three iterations whose batches went out in one write: the send gaps are 0, so they have no log-normal fit,
    while tau(v->r) has one."""
    rec = Recorder(clock=lambda: 0.0)
    t = 1.0
    for i in range(3):
        rec.on_request(Request(f"v{i}", "VisionRequest", {}, t))
        rec.on_response(Response(f"v{i}", "VisionResponse", {"sharpness": float(i)}, t, t + 0.05))
        t += 0.051 + 0.0003 * i
        for k, skill in enumerate(("set_speed", "move_rel_tool", "break")):
            mid = f"{i}{k}000000"
            args = (0.0, 0.0, 2.0, 0.0, 0.0, 0.0) if skill == "move_rel_tool" else ()
            rec.on_send(SentMessage(mid, skill, args, i + 1, t))
            done = 10.0 * i + (0.15 if skill == "break" else 0.001)
            rec.on_ack(MessageResult(mid, skill, args, i + 1, t, t + 0.155 + 0.001 * k,
                                     Ack(mid, Status.DONE, 10.0 * i, done, Pose())))
        t += 0.16
    return rec.save(tmp_path / "run")


def test_every_row_of_a_family_names_it_the_same_way(tmp_path):
    from rich.console import Console

    summary = analyze_runs([_one_write_run(tmp_path)], plots=False)
    assert summary.fits["tau_ss_to_mrt_ms"] is None and summary.fits["tau_v_to_r_ms"] is not None  # both kinds
    console = Console(record=True, width=200)
    console.print(fits_table(summary))
    rows = {line.split("│")[1].strip(): line.split("│")[2].strip() for line in console.export_text().splitlines()
            if line.count("│") >= 4 and "quantity" not in line}
    for q in QUANTITIES:
        assert rows[q.symbol] == FAMILY_NAMES[q.family], (q.symbol, rows)
    assert set(rows.values()) == {"Gaussian", "log-normal"}
