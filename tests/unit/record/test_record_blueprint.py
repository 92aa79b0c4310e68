"""Every recording opens in the same layout: the cell in 3D, the camera, the sharpness, the message log, the Gantt
rows, latencies and joints, each view rooted at an entity the CellLogger writes."""

from __future__ import annotations

import warnings

import pytest

pytest.importorskip("rerun")

from aioadept.record.live import RunRecording  # noqa: E402
from aioadept.record.read import blueprint_views  # noqa: E402
from aioadept.record.rrd import default_blueprint  # noqa: E402


def test_the_layout_builds_without_a_rerun_warning():
    # Rerun drops a component it cannot convert with only a warning (a legend corner given as a string did).
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        default_blueprint()


def test_a_recording_file_carries_the_layout(tmp_path):
    with RunRecording(tmp_path / "run.rrd"):
        pass
    views = {v["name"]: (v["kind"], v["origin"]) for v in blueprint_views(tmp_path / "run.rrd")}
    assert views == {
        "Cell (base frame, mm)": ("3D", "world"),
        "Messages": ("TextLog", "messages"),
        "Camera": ("2D", "camera/image"),
        "Sharpness": ("TimeSeries", "focus/sharpness"),
        "In flight (Fig. 10 rows)": ("TimeSeries", "timeline"),
        "Latency (ms)": ("TimeSeries", "/"),
        "Joints (deg)": ("TimeSeries", "robot/joints_deg"),
    }


def test_a_file_without_a_layout_has_no_views(tmp_path):
    import rerun as rr

    rec = rr.RecordingStream("aioadept")
    rec.set_sinks(rr.FileSink(str(tmp_path / "bare.rrd")))
    rec.log("focus/sharpness", rr.Scalars(1.0))
    rec.flush()
    rec.disconnect()
    assert blueprint_views(tmp_path / "bare.rrd") == []
