"""run.json says what the run folder lacks, also when the disk is too full for a temporary file."""

from __future__ import annotations

import errno
import json

from aioadept.runs import capture
from aioadept.analysis.synthetic import synthetic_recorder
from aioadept.runs.capture import RUN_JSON_RESERVE, note_not_written


def _run(path):
    rec, params = synthetic_recorder(seed=2, n_steps=3)
    return rec.save(path, metadata=params)


def test_run_json_lists_nothing_not_written_and_keeps_a_reserve(tmp_path):
    run_dir = _run(tmp_path / "run")
    text = (run_dir / "run.json").read_text()
    assert json.loads(text)["not_written"] == {}
    assert text.endswith(" " * (RUN_JSON_RESERVE - 1) + "\n")


def test_outputs_that_failed_later_are_added_to_run_json(tmp_path):
    run_dir = _run(tmp_path / "run")
    assert note_not_written(run_dir, {"run.rrd": "cut short"})
    assert note_not_written(run_dir, {"fig09_sharpness.png": "No space left on device"})
    info = json.loads((run_dir / "run.json").read_text())
    assert info["not_written"] == {"run.rrd": "cut short", "fig09_sharpness.png": "No space left on device"}
    assert info["counts"]["robot"] > 0  # the rest is kept


def no_room(path, binary):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_a_disk_too_full_for_a_temporary_file_gets_the_list_in_place(tmp_path, monkeypatch):
    run_dir = _run(tmp_path / "run")
    size = (run_dir / "run.json").stat().st_size
    monkeypatch.setattr(capture, "_open_for_write", no_room)
    assert note_not_written(run_dir, {"frames/frames.csv": "not written", "summary.json": "No space left on device"})
    assert (run_dir / "run.json").stat().st_size == size  # overwritten within its reserve: no new block needed
    assert json.loads((run_dir / "run.json").read_text())["not_written"] == {
        "frames/frames.csv": "not written", "summary.json": "No space left on device"}
    assert not [p for p in run_dir.iterdir() if p.name.startswith(".")]


def test_a_list_longer_than_the_reserve_is_refused_and_run_json_is_unchanged(tmp_path, monkeypatch):
    run_dir = _run(tmp_path / "run")
    before = (run_dir / "run.json").read_bytes()
    monkeypatch.setattr(capture, "_open_for_write", no_room)
    assert not note_not_written(run_dir, {f"file{i}.png": "x" * 100 for i in range(40)})
    assert (run_dir / "run.json").read_bytes() == before
    assert not note_not_written(tmp_path / "no-such-run", {"a": "b"})
