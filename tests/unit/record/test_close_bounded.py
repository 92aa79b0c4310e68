"""Closing a recording never hangs: a dead Rerun file writer (full disk) is given up on after the timeout."""

from __future__ import annotations

import threading
import time

import pytest

from aioadept.record.sinks import close_bounded


class _StuckRecording:
    """The shape of a RecordingStream whose file writer died: flush waits for ever (until released)."""

    def __init__(self) -> None:
        self.release = threading.Event()
        self.disconnected = False

    def flush(self, *, timeout_sec: float) -> None:
        self.release.wait()

    def disconnect(self) -> None:
        self.disconnected = True


class _FailingRecording:
    def flush(self, *, timeout_sec: float) -> None:
        raise RuntimeError("File-writer thread shut down")

    def disconnect(self) -> None:
        pass


@pytest.mark.timeout(10)
def test_a_stuck_writer_is_given_up_on_after_the_timeout():
    rec = _StuckRecording()
    t0 = time.monotonic()
    errors = close_bounded(rec, 0.2)
    assert time.monotonic() - t0 < 3.0
    assert errors and "did not finish within 0.2 s" in errors[0]
    rec.release.set()  # let the daemon thread end


def test_a_sink_error_is_returned_not_raised():
    assert close_bounded(_FailingRecording(), 1.0) == ["RuntimeError: File-writer thread shut down"]


def test_a_real_recording_closes_cleanly(tmp_path):
    rr = pytest.importorskip("rerun")
    rec = rr.RecordingStream("aioadept-test")
    rec.set_sinks(rr.FileSink(str(tmp_path / "x.rrd")))
    rec.log("a", rr.Scalars(1.0))
    assert close_bounded(rec, 5.0) == []
    assert (tmp_path / "x.rrd").stat().st_size > 0
