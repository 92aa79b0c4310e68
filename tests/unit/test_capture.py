"""Recorder: observer hooks -> records -> run folder -> load_run, and the documented columns."""

from __future__ import annotations

import asyncio
import errno
import os
import csv
import json
import pytest

from aioadept.bus import Request, Response
from aioadept.runs.capture import MARK_COLUMNS, ROBOT_COLUMNS, VISION_COLUMNS, Recorder, load_run
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
    pa.ArrowException = type("ArrowException", (Exception,), {})

    def write_table(table, where):  # pyarrow writes to a path or an open file; the run folder gives it a file
        written[tuple(table)] = table
        where.write(b"PAR1")

    pq.write_table = write_table
    pa.parquet = pq
    monkeypatch.setitem(sys.modules, "pyarrow", pa)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", pq)
    out = _filled().save(tmp_path / "pq")
    for name, columns in (("robot", ROBOT_COLUMNS), ("vision", VISION_COLUMNS), ("marks", MARK_COLUMNS)):
        assert (out / f"{name}.parquet").read_bytes() == b"PAR1"
        written[f"{name}.parquet"] = written.pop(tuple(columns))
    assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")]
    assert tuple(written["robot.parquet"]) == ROBOT_COLUMNS
    assert written["robot.parquet"]["t_recv_s"] == [100.0523, 100.0531, None, 100.41]
    info = json.loads((out / "run.json").read_text())
    assert "robot.parquet" in info["files"]


# ------------------------------------------------------------------ a full disk never costs what was written before
class _FullDisk:
    """A file whose writes fail with ENOSPC once ``room`` bytes went through (what a full disk does mid-file)."""

    def __init__(self, f, room):
        self._f, self._room = f, room

    def write(self, data):
        if len(data) > self._room:
            self._f.write(data[: self._room])
            self._room = 0
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self._room -= len(data)
        return self._f.write(data)

    def __getattr__(self, name):
        return getattr(self._f, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._f.close()


def _disk_full_for(monkeypatch, names, room=10):
    from aioadept.runs import capture

    real = capture._open_for_write

    def opener(path, binary):
        f = real(path, binary)
        return _FullDisk(f, room) if any(path.name.startswith(f".{n}.") for n in names) else f

    monkeypatch.setattr(capture, "_open_for_write", opener)


def test_a_full_disk_keeps_the_previous_files_whole_and_names_what_was_not_written(tmp_path, monkeypatch):
    from aioadept.errors import RunSaveError

    out = _filled().save(tmp_path / "r", metadata={"try": 1})
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    rec = _filled()
    rec.mark("more", 2)  # the second save has different content
    _disk_full_for(monkeypatch, ["robot.csv"])
    with pytest.raises(RunSaveError) as info:
        rec.save(out, metadata={"try": 2})
    err = info.value
    assert set(err.not_written) == {"robot.csv", "run.json"}
    assert "No space left on device" in err.not_written["robot.csv"]
    assert "robot.csv" in str(err) and "run.json" in str(err)
    assert {n for n in err.written if not n.endswith(".parquet")} == {"vision.csv", "marks.csv"}  # parquet: optional
    # robot.csv and run.json are exactly the previous ones (not truncated); no temporary file is left behind.
    assert (out / "robot.csv").read_bytes() == before["robot.csv"]
    assert (out / "run.json").read_bytes() == before["run.json"]
    assert (out / "marks.csv").read_bytes() != before["marks.csv"]
    assert sorted(p.name for p in out.iterdir()) == sorted(before)
    assert load_run(out).parameters == {"try": 1}  # the folder still reads back as the complete first save


def test_a_full_disk_at_run_json_reports_it_and_leaves_no_partial_run_json(tmp_path, monkeypatch):
    from aioadept.errors import RunSaveError

    _disk_full_for(monkeypatch, ["run.json"])
    with pytest.raises(RunSaveError) as info:
        _filled().save(tmp_path / "r")
    assert list(info.value.not_written) == ["run.json"]
    assert not (tmp_path / "r" / "run.json").exists()
    names = sorted(p.name for p in (tmp_path / "r").iterdir() if p.suffix != ".parquet")  # parquet: optional
    assert names == ["marks.csv", "robot.csv", "vision.csv"]


def test_write_atomic_replaces_whole_or_not_at_all(tmp_path, monkeypatch):
    from aioadept.runs.capture import write_atomic

    target = tmp_path / "focus.json"
    write_atomic(target, '{"old": true}')
    _disk_full_for(monkeypatch, ["focus.json"], room=3)
    with pytest.raises(OSError) as info:
        write_atomic(target, '{"new": "a longer result"}')
    assert info.value.errno == errno.ENOSPC
    assert target.read_text() == '{"old": true}'
    assert [p.name for p in tmp_path.iterdir()] == ["focus.json"]


def test_a_run_folder_that_cannot_be_created_is_a_run_save_error(tmp_path):
    from aioadept.errors import RunSaveError

    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the run folder's parent should be")
    with pytest.raises(RunSaveError) as info:
        _filled().save(blocker / "r")
    assert set(info.value.not_written) == {"robot.csv", "vision.csv", "marks.csv", "run.json"}
    assert "cannot create the folder" in str(info.value)
