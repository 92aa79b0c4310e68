"""Recorder: observer hooks -> records -> run folder -> load_run, and the documented columns."""

from __future__ import annotations

import asyncio
import csv
import json
import pytest

from aioadept.bus import Request, Response
from aioadept.capture import MARK_COLUMNS, ROBOT_COLUMNS, VISION_COLUMNS, Recorder, load_run
from aioadept.client import MessageResult, SentMessage
from aioadept.geometry import Pose
from aioadept.protocol import Ack, Status


POSE = Pose(480.014, -0.038, 709.975, 0.0, 179.995, 0.004)


def _ack(mid: str, t0: float, t1: float, status: Status = Status.DONE, extra: tuple[str, ...] = ()) -> Ack:
    return Ack(mid, status, t0, t1, POSE, extra)


def _filled() -> Recorder:
    t = [100.0]
    rec = Recorder(clock=lambda: t[0])
    calls = [("0a000001", "set_speed", (20,)), ("0a000002", "move_rel_tool", (0.0, 0.0, 2.5, 0.0, 0.0, 0.0)),
             ("0a000003", "break", ())]
    rec.mark("phase", "approach")
    rec.on_request(Request("req00001", "VisionRequest", {"t_request": 1.7e9}, 100.001))
    rec.on_request(Request("req00001", "VisionRequest", {"t_request": 1.7e9}, 100.011))  # re-published, same id
    rec.on_response(Response("req00001", "VisionResponse",
                             {"sharpness": 12.5, "frame_t": 1.7e9 + 0.04, "proc_time_ms": 11.25, "camera": "c1"},
                             100.001, 100.05))
    rec.on_request(Request("req00002", "VisionRequest", {}, 100.3))  # never answered
    for mid, skill, args in calls:
        rec.on_send(SentMessage(mid, skill, args, 7, 100.0511))
    rec.on_ack(MessageResult("0a000001", "set_speed", (20,), 7, 100.0511, 100.0523, _ack("0a000001", 10.001, 10.001)))
    rec.on_ack(MessageResult("0a000002", "move_rel_tool", calls[1][2], 7, 100.0511, 100.0531,
                             _ack("0a000002", 10.001, 10.002)))
    # 0a000003 (break) never acked: the connection dropped.
    rec.on_send(SentMessage("0a000004", "move_to", (1.0, 2.0, 3.0, 4.0, 5.0, 6.0), 8, 100.4))
    rec.on_ack(MessageResult("0a000004", "move_to", (1.0, 2.0, 3.0, 4.0, 5.0, 6.0), 8, 100.4, 100.41,
                             _ack("0a000004", 10.4, 10.4, Status.ERROR, ("-1012", "location out of reach, x"))))
    t[0] = 100.5
    rec.mark("iteration", 3)
    rec.mark("meta", {"a": [1, 2]}, t_s=101.25)
    return rec


def test_snapshot_pairs_sends_with_acks_and_keeps_unacked_messages() -> None:
    run = _filled().snapshot()
    assert [r.id for r in run.robot] == ["0a000001", "0a000002", "0a000003", "0a000004"]
    ss, mrt, brk, mto = run.robot
    assert (ss.skill, ss.args, ss.batch, ss.t_send_s, ss.t_recv_s) == ("set_speed", (20,), 7, 100.0511, 100.0523)
    assert (mrt.t_start_s, mrt.t_done_s, mrt.status, mrt.pose) == (10.001, 10.002, "done", POSE)
    assert brk.t_send_s == 100.0511 and not brk.acked
    assert (brk.t_recv_s, brk.t_start_s, brk.t_done_s, brk.status, brk.pose) == (None,) * 5
    assert (mto.status, mto.error_code, mto.error_message) == ("error", -1012, "location out of reach, x")
    v1, v2 = run.vision
    assert (v1.t_send_s, v1.t_recv_s, v1.attempts) == (100.001, 100.05, 2)  # first publish is the send time
    assert (v1.sharpness, v1.frame_t_epoch_s, v1.proc_time_ms, v1.error) == (12.5, 1.7e9 + 0.04, 11.25, None)
    assert v1.response_extra == {"camera": "c1"} and v1.request_attributes == {"t_request": 1.7e9}
    assert not v2.answered and v2.sharpness is None
    assert [(m.t_s, m.name, m.value) for m in run.marks] == [
        (100.0, "phase", "approach"), (100.5, "iteration", 3), (101.25, "meta", {"a": [1, 2]})]


def test_save_then_load_gives_the_same_records(tmp_path) -> None:
    rec = _filled()
    out = rec.save(tmp_path / "run1", metadata={"appr_speed": 25, "delta_z_mm": 2.0})
    loaded = load_run(out)
    mem = rec.snapshot()
    assert loaded.robot == mem.robot  # floats survive exactly (repr), poses and Nones too
    assert loaded.vision == mem.vision
    assert loaded.marks == mem.marks
    assert loaded.parameters == {"appr_speed": 25, "delta_z_mm": 2.0}
    assert loaded.name == "run1" and loaded.path == out


def test_run_json_and_csv_headers_follow_the_documented_format(tmp_path) -> None:
    rec = _filled()
    out = rec.save(tmp_path / "r", metadata={"note": "x"})
    info = json.loads((out / "run.json").read_text())
    from aioadept import __version__

    assert info["format"] == "aioadept-run" and info["format_version"] == 1
    assert info["aioadept_version"] == __version__
    assert info["parameters"] == {"note": "x"}
    assert info["counts"] == {"robot": 4, "vision": 2, "marks": 3}
    assert info["start_loop_s"] == 100.0 and info["start_wall_time_utc"].endswith("+00:00")
    assert info["host"] and "t_send_s/t_recv_s" in info["clocks"]
    assert sorted(info["files"]) == sorted(p.name for p in out.iterdir() if p.name != "run.json")
    for name, cols in (("robot", ROBOT_COLUMNS), ("vision", VISION_COLUMNS), ("marks", MARK_COLUMNS)):
        with (out / f"{name}.csv").open(newline="") as f:
            assert tuple(next(csv.reader(f))) == cols
    # an unacked message has empty receive/server cells, not zeros
    with (out / "robot.csv").open(newline="") as f:
        brk = [r for r in csv.DictReader(f) if r["skill"] == "break"][0]
    assert brk["t_recv_s"] == brk["t_start_s"] == brk["status"] == brk["pose_z_mm"] == ""


def test_snapshot_carries_parameters_for_in_memory_analysis() -> None:
    run = _filled().snapshot(metadata={"approach_speed": 5})
    assert run.parameters == {"approach_speed": 5} and run.path is None and run.name == "run"


def test_ack_without_a_seen_send_is_kept() -> None:
    rec = Recorder(clock=lambda: 0.0)
    rec.on_ack(MessageResult("0b000001", "here", (), 3, 5.0, 5.5, _ack("0b000001", 1.0, 1.0)))
    (row,) = rec.snapshot().robot
    assert (row.id, row.skill, row.batch, row.t_send_s, row.t_recv_s) == ("0b000001", "here", 3, 5.0, 5.5)


async def test_marks_use_the_running_loop_clock() -> None:
    rec = Recorder()
    loop = asyncio.get_running_loop()
    before = loop.time()
    rec.mark("iteration", 0)
    after = loop.time()
    (m,) = rec.snapshot().marks
    assert before <= m.t_s <= after


def test_hooks_only_append() -> None:
    # The hot path must not pair, copy or format: the stored object is the one passed in.
    rec = Recorder(clock=lambda: 0.0)
    msg = SentMessage("0c000001", "break", (), 1, 1.0)
    rec.on_send(msg)
    assert rec._sends[-1] is msg


def test_load_run_errors(tmp_path) -> None:
    with pytest.raises(FileNotFoundError):
        load_run(tmp_path / "missing")
    out = _filled().save(tmp_path / "r")
    (out / "vision.csv").write_text("seq,id\n0,x\n")
    with pytest.raises(ValueError, match="missing columns"):
        load_run(out)


def test_parquet_copies_when_pyarrow_imports(tmp_path, monkeypatch) -> None:
    # pyarrow is optional and not installed here: a stand-in records what would be written.
    import sys
    import types

    written = {}
    pa = types.ModuleType("pyarrow")
    pa.table = lambda data: data
    pq = types.ModuleType("pyarrow.parquet")
    pq.write_table = lambda table, path: written.__setitem__(path.name, table)
    pa.parquet = pq
    monkeypatch.setitem(sys.modules, "pyarrow", pa)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", pq)
    out = _filled().save(tmp_path / "pq")
    assert sorted(written) == ["marks.parquet", "robot.parquet", "vision.parquet"]
    assert tuple(written["robot.parquet"]) == ROBOT_COLUMNS
    assert written["robot.parquet"]["t_recv_s"] == [100.0523, 100.0531, None, 100.41]
    info = json.loads((out / "run.json").read_text())
    assert "robot.parquet" in info["files"]
