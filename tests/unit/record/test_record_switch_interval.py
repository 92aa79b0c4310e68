"""A running RunRecording asked to (as the CLIs do) shortens the GIL switch interval (its worker must not hold the MCN's event loop off for
Python's default 5 ms per burst) and gives the old value back when the last one closes."""

from __future__ import annotations

import sys

import pytest

pytest.importorskip("rerun")

from aioadept.record.live import SWITCH_INTERVAL_S, RunRecording  # noqa: E402


def test_switch_interval_short_while_recording_and_restored_after(tmp_path):
    before = sys.getswitchinterval()
    assert before > SWITCH_INTERVAL_S  # Python's default, 5 ms
    a = RunRecording(tmp_path / "a.rrd", short_switch_interval=True).start()
    b = RunRecording(tmp_path / "b.rrd", short_switch_interval=True).start()
    try:
        assert sys.getswitchinterval() == pytest.approx(SWITCH_INTERVAL_S)
        a.close()
        assert sys.getswitchinterval() == pytest.approx(SWITCH_INTERVAL_S)  # b still records
    finally:
        a.close()
        b.close()
    assert sys.getswitchinterval() == before
    b.close()  # idempotent: no second restore
    assert sys.getswitchinterval() == before


def test_a_library_recording_leaves_the_process_wide_setting_alone(tmp_path):
    before = sys.getswitchinterval()
    with RunRecording(tmp_path / "c.rrd"):
        assert sys.getswitchinterval() == before
    assert sys.getswitchinterval() == before
