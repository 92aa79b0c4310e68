"""run.rrd is there whole or not at all: a full disk must not leave it cut short under its name.
Rerun's file sink reports a failed write only in its own log, so completeness is read from the file's footer."""

from __future__ import annotations

import pytest

pytest.importorskip("rerun")

from aioadept.record.live import RunRecording  # noqa: E402
from aioadept.record.sinks import rrd_incomplete  # noqa: E402


def test_a_closed_recording_is_renamed_into_place_whole_and_no_temporary_file_is_left(tmp_path):
    rec = RunRecording(tmp_path / "run.rrd")
    with rec:
        assert not (tmp_path / "run.rrd").exists()  # written under a temporary name while it runs
    assert rec.error is None
    assert rrd_incomplete(tmp_path / "run.rrd") is None
    assert [p.name for p in tmp_path.iterdir()] == ["run.rrd"]


@pytest.mark.parametrize("keep", [1, 12, 100, 0.5])
def test_a_recording_cut_short_is_found_incomplete(tmp_path, keep):
    with RunRecording(tmp_path / "run.rrd"):
        pass
    data = (tmp_path / "run.rrd").read_bytes()
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(data[: int(len(data) * keep)] if isinstance(keep, float) else data[:-keep])
    why = rrd_incomplete(cut)
    assert why is not None and why.startswith("cut short"), why
    assert rrd_incomplete(tmp_path / "missing.rrd") == "not written"
