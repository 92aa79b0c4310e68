"""run.rrd of real runs (the demo's sim and vision node processes), the viewer's bind address, and --view without
the extra; the recording's content is read back through Rerun's own reader."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rerun")

from aioadept.record.read import blueprint_views, read_rrd  # noqa: E402

AIOADEPT = str(Path(sys.executable).parent / "aioadept")


def _demo(out: Path, *extra: str) -> Path:
    env = {**os.environ, "COLUMNS": "120"}
    proc = subprocess.run([AIOADEPT, "demo", "--time-scale", "20", "--no-analyze", "--out", str(out), *extra],
                          capture_output=True, text=True, timeout=100, env=env, stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = [p for p in out.iterdir() if p.is_dir()]
    return run_dir


@pytest.mark.timeout(120)
def test_a_demo_run_records_robot_messages_frames_sharpness_and_the_focus_plane(tmp_path):
    run_dir = _demo(tmp_path / "runs")
    rows = read_rrd(run_dir / "run.rrd")
    focus = json.loads((run_dir / "focus.json").read_text())
    robot_csv = (run_dir / "robot.csv").read_text().splitlines()
    vision_csv = (run_dir / "vision.csv").read_text().splitlines()
    # every command and every ack, every request and every response
    assert len(rows["/messages/robot"]) == 2 * (len(robot_csv) - 1)
    assert len(rows["/messages/vision"]) == 2 * (len(vision_csv) - 1)
    # the sharpness after each step, in order, as the application found it
    assert [r["Scalars:scalars"][0] for r in rows["/focus/sharpness"]] == pytest.approx(focus["sharpness"])
    assert [r["step"] for r in rows["/focus/sharpness"]] == list(range(len(focus["sharpness"])))
    # each processed frame, at the exposure time of its sharpness
    images = rows["/camera/image"]
    assert len(images) == len(focus["sharpness"])
    assert [r["time"] for r in images] == pytest.approx([r["time"] for r in rows["/focus/sharpness"]])
    # the arm from the sim's state stream, the tool frame, the targets, the focus plane at the inspection pose
    assert len(rows["/world/robot/links"]) >= 5
    assert rows["/world/robot/tool"] and rows["/world/targets"]
    plane = rows["/world/focus_plane"]
    assert len(plane) == 1
    ip = focus["inspection_pose"]
    np.testing.assert_allclose(plane[0]["Boxes3D:centers"][0], [ip["x"], ip["y"], ip["z"]], atol=1e-2)
    assert rows["/focus/plane_offset_mm"][0]["Scalars:scalars"][0] == pytest.approx(focus["peak_offset_mm"], abs=1e-3)
    # the analysis rebuilds the same messages, sharpness and plane from the CSV logs of the same folder
    from aioadept.record.from_csv import rrd_from_run

    again = read_rrd(rrd_from_run(run_dir, tmp_path / "from_csv.rrd"))
    for entity in ("/messages/robot", "/messages/vision", "/focus/sharpness", "/camera/image",
                   "/timeline/robot_in_flight", "/timeline/vision_in_flight", "/world/focus_plane"):
        assert len(again[entity]) == len(rows[entity]), entity
    assert [r["time"] for r in again["/focus/sharpness"]] == pytest.approx(
        [r["time"] for r in rows["/focus/sharpness"]], abs=1e-6)
    # both open in the same layout: the cell in 3D, the camera, the sharpness, the message log, each view's
    # origin an entity the run actually logged
    for rrd, content in ((run_dir / "run.rrd", rows), (tmp_path / "from_csv.rrd", again)):
        views = {v["name"]: v for v in blueprint_views(rrd)}
        assert (views["Cell (base frame, mm)"]["kind"], views["Cell (base frame, mm)"]["origin"]) == ("3D", "world")
        assert (views["Camera"]["kind"], views["Camera"]["origin"]) == ("2D", "camera/image")
        assert (views["Sharpness"]["kind"], views["Sharpness"]["origin"]) == ("TimeSeries", "focus/sharpness")
        assert views["Messages"]["kind"] == "TextLog"
        for v in views.values():
            if v["origin"] != "/":
                assert any(e == "/" + v["origin"] or e.startswith(f"/{v['origin']}/") for e in content), v


@pytest.mark.timeout(60)
def test_the_viewer_binds_loopback_only_unless_told(tmp_path):
    import psutil

    from aioadept.record.viewer import ViewerServer

    with ViewerServer() as v:
        listening = {(c.laddr.ip, c.laddr.port) for c in psutil.Process(v.proc.pid).net_connections("inet")
                     if c.status == psutil.CONN_LISTEN}
        assert (("127.0.0.1", v.grpc_port) in listening) and (("127.0.0.1", v.web_port) in listening), listening
        assert all(ip == "127.0.0.1" for ip, _ in listening), listening
        assert v.url.startswith(f"http://127.0.0.1:{v.web_port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A")
        # analytics off in the child's own configuration, the user's untouched
        cfg_file = Path(v._tmp.name) / "config" / "rerun" / "analytics.json"
        assert json.loads(cfg_file.read_text())["analytics_enabled"] is False
        pid = v.proc.pid
    assert not psutil.pid_exists(pid) or psutil.Process(pid).status() == psutil.STATUS_ZOMBIE


@pytest.mark.timeout(60)
@pytest.mark.parametrize("command", ["demo", "focus", "experiment"])
def test_view_without_the_extra_says_how_to_install_it_in_one_line(tmp_path, command):
    # rerun made unimportable in the child: what a machine without the [viewer] extra sees
    out = tmp_path / "out"
    code = ("import sys; sys.modules['rerun'] = None; sys.modules['rerun_cli'] = None\n"
            "from aioadept.cli import main\n"
            f"sys.exit(main([{command!r}, '--view', '--out', {str(out)!r}]))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=50,
                          stdin=subprocess.DEVNULL)
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if "--view" in ln]
    assert len(lines) == 1 and "pip install 'aioadept[viewer]'" in lines[0], proc.stderr
    assert lines[0].startswith(f"aioadept {command}: --view: ")
    assert "Traceback" not in proc.stderr
    assert not out.exists() or not any(out.iterdir()), "the mistake left a run folder behind"
