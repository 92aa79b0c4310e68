"""``aioadept calibrate`` and its routine against the simulated robot over real TCP and a locator node over real
ZeroMQ on 127.0.0.1, whose camera renders a marker carried by the sim's tool (aioadept.vision.synthetic: the
world camera does not draw a marker on the tool) from a camera pose the routine does not know."""

from __future__ import annotations

import asyncio
import contextlib
import importlib.util
import os
import subprocess
import sys
import time
import tomllib

import pytest

from aioadept.bus.communicator import Communicator
from aioadept.geometry import Pose, pose_error, trans
from aioadept.testing.sim import running_sim
from aioadept.vision.calibration import CameraCalibration
from aioadept.vision.sources import Camera, Frame
from aioadept.vision.synthetic import render

TRUTH = CameraCalibration(x_mm=455.0, y_mm=8.0, z_mm=910.0, yaw_deg=2.0, pitch_deg=178.5, roll_deg=-1.0)
NOMINAL = CameraCalibration()  # what the routine starts from: the cell file's default camera, 1-2 cm and deg off
TOOL_FROM_MARKER = trans(0.0, 0.0, 5.0, 0.0, 180.0, 0.0)  # a plate on the flange facing back up the tool axis
MARKER = 7


class ToolMarkerCamera(Camera):
    """Renders the marker at the sim controller's current tool pose, seen by the TRUTH camera."""

    camera_id = "tool-marker"

    def __init__(self, controller) -> None:  # noqa: ANN001
        self.controller = controller
        self.seq = 0

    def grab(self) -> Frame:
        time.sleep(0.02)
        t = time.time()
        base_from_marker = self.controller.here.to_matrix() @ TOOL_FROM_MARKER
        img = render(TRUTH, markers=[(base_from_marker, MARKER, 40.0)], seed=self.seq)
        self.seq += 1
        return Frame(img, t, self.camera_id, self.seq)


@contextlib.asynccontextmanager
async def cell():
    from aioadept.vision.acquisition import Acquisition
    from aioadept.vision.locate_node import LocatorNode, locate_responder

    async with running_sim(time_scale=20.0) as sim:
        with Acquisition([ToolMarkerCamera(sim.controller)], fps=None) as acq:
            node = LocatorNode(acq, NOMINAL, policy="after", timeout_s=2.0)
            try:
                async with locate_responder("tcp://127.0.0.1:0", "tcp://127.0.0.1:0", node) as responder:
                    yield sim, responder
            finally:
                node.close()


def check(cal: CameraCalibration) -> tuple[float, float]:
    err_mm, err_deg = pose_error(cal.pose, TRUTH.pose)
    assert err_mm <= 1.0 and err_deg <= 0.1, (err_mm, err_deg)
    assert cal.fx_px == NOMINAL.fx_px and cal.rms_px < 0.5
    return err_mm, err_deg


@pytest.mark.timeout(60)
async def test_the_routine_moves_through_the_poses_and_recovers_the_camera():
    from aioadept.apps.calibrate import calibrate, calibration_poses
    from aioadept.client.robot import RobotClient

    poses = calibration_poses(Pose(450.0, 0.0, 300.0, 0.0, 180.0, 0.0), 10, seed=1)
    async with cell() as (sim, responder):
        async with RobotClient(sim.host, sim.port) as robot, \
                Communicator(responder.peer_request_endpoint, responder.peer_response_endpoint,
                             timeout_s=5.0) as comm:
            run = await calibrate(robot, comm, poses, NOMINAL, marker=MARKER, marker_mm=40.0, speed=50)
    assert len(run.views) == 10 and run.skipped == ()
    for view, asked in zip(run.views, poses, strict=True):  # the acked poses, where the robot really was
        assert pose_error(view.tool, asked)[0] < 0.1
    err = check(run.calibration)
    print("calibration error mm, deg:", err, "rms px:", run.calibration.rms_px)


@pytest.mark.timeout(60)
async def test_a_wrong_marker_id_fails_with_too_few_views_and_a_low_pose_moves_nothing():
    from aioadept.apps.calibrate import calibrate, calibration_poses
    from aioadept.errors import CalibrationError
    from aioadept.client.robot import RobotClient

    poses = calibration_poses(Pose(450.0, 0.0, 300.0, 0.0, 180.0, 0.0), 4, seed=2)
    async with cell() as (sim, responder):
        async with RobotClient(sim.host, sim.port) as robot, \
                Communicator(responder.peer_request_endpoint, responder.peer_response_endpoint,
                             timeout_s=5.0) as comm:
            with pytest.raises(CalibrationError, match="only 0 of 4 views saw marker 8"):
                await calibrate(robot, comm, poses, NOMINAL, marker=8, marker_mm=40.0, speed=50)
            start = await robot.here()
            low = [*poses[:3], Pose(450.0, 0.0, 50.0, 0.0, 180.0, 0.0)]
            with pytest.raises(CalibrationError, match="pose 3: z = 50 mm is below"):
                await calibrate(robot, comm, low, NOMINAL, marker=MARKER, marker_mm=40.0)
            assert pose_error(await robot.here(), start)[0] < 1e-6  # refused before any motion


def cli_args(sim, responder, *more: str) -> list[str]:
    return [sys.executable, "-m", "aioadept", "calibrate", "--robot", f"{sim.host}:{sim.port}",
            "--request-endpoint", responder.peer_request_endpoint, "--response-endpoint",
            responder.peer_response_endpoint, "--marker", str(MARKER), "--centre", "450,0,300", *more]


@pytest.mark.timeout(90)
async def test_aioadept_calibrate_writes_the_table_into_the_cell_file(tmp_path):
    cell_file = tmp_path / "cell.toml"
    cell_file.write_text("[focus]\nmax_steps = 12\n", encoding="utf-8")
    async with cell() as (sim, responder):
        proc = await asyncio.create_subprocess_exec(
            *cli_args(sim, responder, "--views", "8", "--speed", "50", "--write", str(cell_file)),
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
        out, err = await proc.communicate()
    assert proc.returncode == 0, err.decode()
    printed = tomllib.loads(out.decode())["calibration"]
    data = tomllib.loads(cell_file.read_text(encoding="utf-8"))
    assert data["focus"] == {"max_steps": 12} and data["calibration"] == printed and printed["views"] == 8
    check(CameraCalibration.from_table(data["calibration"]))


@pytest.mark.timeout(90)
async def test_ctrl_c_stops_the_arm_mid_motion_and_moves_nothing_more(tmp_path):
    import signal

    async with cell() as (sim, responder):
        sim.controller  # noqa: B018
        proc = await asyncio.create_subprocess_exec(
            *cli_args(sim, responder, "--views", "6", "--speed", "100", "--write", str(tmp_path / "c.toml")),
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
        # time_scale 20 in cell(): wait for the first view's answer, then interrupt the second motion
        deadline = time.monotonic() + 30
        while responder.handled < 1 and time.monotonic() < deadline:
            await asyncio.sleep(0.005)
        assert responder.handled >= 1
        proc.send_signal(signal.SIGINT)
        out, err = await proc.communicate()
        served = responder.handled
        t = sim.now()
        moving = sim.controller.trajectory.in_motion(t)
        here = sim.controller.here_at(t)
        await asyncio.sleep(0.3)
        later = sim.controller.here_at(sim.now())
    assert proc.returncode == 130, err.decode()
    assert not moving and pose_error(here, later)[0] < 1e-6  # at rest, and nothing moved it after the exit
    assert served <= 2 and not (tmp_path / "c.toml").exists()  # no more views, nothing written
    assert "interrupt" in err.decode().lower()


@pytest.mark.timeout(60)
def test_bad_input_is_one_line_and_exit_2_before_anything_moves(tmp_path):
    bad_cell = tmp_path / "bad.toml"
    bad_cell.write_text("[calibration]\npitch_deg = 0.0\n", encoding="utf-8")
    for args, word in [(["--views", "2"], "--views 2"), (["--centre", "1,2"], "--centre"),
                       (["--centre", "450,0,20"], "below the lowest allowed"), (["--robot", "host:0"], "--robot"),
                       (["--config", str(bad_cell)], "does not look down"),
                       (["--config", str(tmp_path / "none.toml")], "no such file"),
                       (["--marker-mm", "0"], "--marker-mm")]:
        # port 9 (discard): nothing listens; a run that got past the checks would fail with exit 1, not 2
        res = subprocess.run([sys.executable, "-m", "aioadept", "calibrate", "--robot", "127.0.0.1:9", *args],
                             capture_output=True, text=True, timeout=30)
        assert res.returncode == 2, (args, res.stderr)
        lines = [ln for ln in res.stderr.strip().splitlines() if ln.strip()]
        assert len(lines) == 1 and word in lines[0], (args, res.stderr)


@pytest.mark.timeout(90)
@pytest.mark.skipif(importlib.util.find_spec("zenoh") is None, reason="the [zenoh] extra (eclipse-zenoh) is not installed")
async def test_calibrate_from_a_zenoh_cell_file_meets_the_locator_on_the_cells_keys(tmp_path):
    """[bus] transport = "zenoh" in the cell file: the requests go to aioadept/<cell>/vision/request through the
    cell's router (this test process), not to the file's ZeroMQ addresses (nobody listens there)."""
    from aioadept.vision.acquisition import Acquisition
    from aioadept.vision.locate_node import LocatorNode, locate_responder

    from bustransports import free_port, start_zenoh_router

    router = start_zenoh_router()
    name = f"cal{os.getpid()}"
    async with running_sim(time_scale=20.0) as sim:
        cell_file = tmp_path / "cell.toml"
        cell_file.write_text(
            f'[robot]\nhost = "{sim.host}"\nport = {sim.port}\nstart_sim = false\n'
            f'[vision]\nstart = false\nrequest_endpoint = "tcp://127.0.0.1:{free_port()}"\n'
            f'response_endpoint = "tcp://127.0.0.1:{free_port()}"\n'
            f'[bus]\ntransport = "zenoh"\ncell = "{name}"\nzenoh_router = "{router}"\nstart_router = false\n',
            encoding="utf-8")
        with Acquisition([ToolMarkerCamera(sim.controller)], fps=None) as acq:
            node = LocatorNode(acq, NOMINAL, policy="after", timeout_s=2.0)
            try:
                async with locate_responder(f"zenoh:aioadept/{name}/vision/request",
                                            f"zenoh:aioadept/{name}/vision/response", node) as responder:
                    proc = await asyncio.create_subprocess_exec(
                        sys.executable, "-m", "aioadept", "calibrate", "--config", str(cell_file), "--marker",
                        str(MARKER), "--centre", "450,0,300", "--views", "6", "--speed", "50",
                        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
                    out, err = await proc.communicate()
                    served = responder.handled
            finally:
                node.close()
    assert proc.returncode == 0, err.decode()
    assert served >= 6
    check(CameraCalibration.from_table(tomllib.loads(out.decode())["calibration"]))
