"""The simulated world through the real pieces, on both backends: a sim process (the Python skills, or the V+
emulator running the shipped vplus/ server) started with a cell file's [world]; a client over TCP closes the hand
on a part, lifts it, carries it and releases it on the table; the world.state stream (ZeroMQ, Protobuf) shows the
part grasped and following the tool, then resting where it was put; the feeder's sensor input goes off as the
part leaves; and a release from high up is an error in the sim's log."""

from __future__ import annotations

import asyncio
from pathlib import Path

import numpy as np
import pytest

from aioadept import Break, CloseHand, OpenHand, Sig
from aioadept.commands import MoveToS, SetSpeed
from aioadept.bus.messages import WORLD_STATE_TOPIC, WorldState
from aioadept.bus.pubsub import Subscriber
from aioadept.client import RobotClient
from aioadept.geometry import Pose
from aioadept.testing.nodes import running_node
from aioadept.ports import free_port

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
HOME = Pose(480.0, 0.0, 710.0, 0.0, 180.0, 0.0)  # the sim's home tool pose (tool pointing down)
TABLE_Z = 380.0

WORLD = f"""
[world]
table_z_mm = {TABLE_Z}
[[world.parts]]
id = 5
shape = "cylinder"
size_mm = [30, 40]
colour = "blue"
marker = 2
x_mm = 480.0
y_mm = 0.0
[world.feeder]
x_mm = 480.0
y_mm = 0.0
sensor = 1002
"""


def sim_args(backend: str, port: int) -> list[str]:
    if backend == "python":
        return ["--port", str(port), "--stop-port", "none"]
    return ["--vplus", str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(VPLUS / "rsconfig.V2"),
            "--run", "rs.main", "--map-port", f"1234={port}", "--map-port", "1235=0", "--map-port", "1236=0"]


async def next_world(sub: Subscriber) -> WorldState:
    return WorldState.from_bytes((await asyncio.wait_for(sub.recv(), 5.0))[1])


async def world_when(sub: Subscriber, part: int, ok, timeout_s: float = 5.0) -> WorldState:
    """The first world sample in which ``ok(part state)`` holds (the V+ server's TIMER and the stream's clock
    need not share their zero, so samples are matched by content, not by an ack's time); TimeoutError if none
    does within ``timeout_s``."""
    async with asyncio.timeout(timeout_s):
        while True:
            st = await next_world(sub)
            if ok(st.part(part)):
                return st


@pytest.mark.timeout(90)
@pytest.mark.parametrize("backend", ["python", "vplus"])
async def test_a_client_picks_carries_and_places_a_part_and_the_stream_follows(backend, tmp_path):
    cell = tmp_path / "cell.toml"
    cell.write_text(WORLD)
    port = free_port()
    async with running_node("sim", *sim_args(backend, port), "--world", str(cell), "--time-scale", "5",
                            "--state-endpoint", "tcp://127.0.0.1:0", "--state-rate-hz", "100",
                            log_path=tmp_path / "sim.log", ready_timeout_s=60) as sim:
        async with Subscriber(sim.ready["state"], topics=[WORLD_STATE_TOPIC]) as sub, \
                RobotClient("127.0.0.1", port) as robot:
            first = await next_world(sub)
            part = first.part(5)
            assert not part.grasped and part.pose.z == pytest.approx(TABLE_Z) and first.sensors_on == (1002,)
            grip = Pose(480.0, 0.0, TABLE_Z + 20.0, 0.0, 180.0, 0.0)
            res = await robot.cmdexec(MoveToS(grip), CloseHand(), Sig(1001, 1002))
            assert Sig.states(res.messages[-1].ack) == (False, False), \
                "closed on the part (the switch stays off) and the feeder is empty"
            up = Pose(480.0, 0.0, TABLE_Z + 150.0, 0.0, 180.0, 0.0)
            res = await robot.cmdexec(MoveToS(up), Break())
            # it follows the tool up (a timeout here says it never got there)
            held = (await world_when(sub, 5, lambda p: abs(p.pose.z - (TABLE_Z + 130.0)) < 0.01)).part(5)
            assert held.grasped and (held.pose.x, held.pose.y) == pytest.approx((480.0, 0.0), abs=0.01)
            place = Pose(400.0, 150.0, TABLE_Z + 21.5, 0.0, 180.0, 0.0)   # its bottom 1.5 mm above the table
            res = await robot.cmdexec(MoveToS(place), OpenHand(), Sig(1002))
            assert Sig.states(res.messages[-1].ack) == (False,)
            p = (await world_when(sub, 5, lambda p: not p.grasped)).part(5)
            assert not p.grasped and not p.dropped
            assert (p.pose.x, p.pose.y, p.pose.z) == pytest.approx((400.0, 150.0, TABLE_Z), abs=0.01)
            # a release from high up: an error in the sim's log, the part on the table below, marked dropped
            await robot.cmdexec(MoveToS(Pose(400.0, 150.0, TABLE_Z + 20.0, 0.0, 180.0, 0.0)), CloseHand(),
                                MoveToS(Pose(400.0, 150.0, TABLE_Z + 100.0, 0.0, 180.0, 0.0)))
            await robot.cmdexec(OpenHand())
            seen = []
            st = await next_world(sub)
            while not st.part(5).dropped:
                seen += st.events
                st = await next_world(sub)           # every sample: each event is sent once
            seen += st.events
            drops = [e for e in seen if e.kind == "dropped"]
            assert len(drops) == 1 and "80.0 mm above the table" in drops[0].text
            assert st.part(5).pose.z == pytest.approx(TABLE_Z)
    log = (tmp_path / "sim.log").read_text()
    assert "dropped: released 80.0 mm above the table" in log, log[-2000:]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("command", [["sim", "--port", "0", "--world"], ["sim", "--port", "0", "--config"],
                                     ["demo", "--config"]])
def test_a_bad_world_value_is_one_line_exit_2_before_anything_starts(command, tmp_path):
    import subprocess
    import sys

    cell = tmp_path / "cell.toml"
    cell.write_text(WORLD.replace('colour = "blue"', 'colour = "blue"\nmarker_mm = 40'))
    proc = subprocess.run([sys.executable, "-m", "aioadept", *command, str(cell)],
                          capture_output=True, text=True, timeout=50, cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert lines == [f"aioadept {command[0]}: {cell} [world] parts[0]: marker_mm = 40: the marker and its white "
                     f"margin do not fit on the part's top face (marker_mm at most 15.9)"], proc.stderr
    assert proc.stdout == "" and not (tmp_path / "runs").exists()


WORLD_CAM = WORLD + """
[world.camera]
x_mm = 450.0
y_mm = 50.0
z_mm = 1000.0
focal_length_mm = 8.0
"""


def marker_in(image_path: Path, marker: int) -> np.ndarray:
    import cv2

    image = cv2.imread(str(image_path), cv2.IMREAD_GRAYSCALE)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    corners, ids, _ = cv2.aruco.ArucoDetector(dictionary, params).detectMarkers(image)
    assert ids is not None and list(ids.ravel()) == [marker], ids
    return corners[0].reshape(4, 2)


@pytest.mark.timeout(90)
async def test_the_vision_node_sees_the_part_where_the_world_stream_puts_it(tmp_path):
    """``aioadept vision --source world``: the frame that answers a request shows the part's marker where the
    published world state puts it, before and after the robot carries the part away."""
    from aioadept.bus.communicator import Communicator
    from aioadept.vision.world_camera import WorldView
    from aioadept.cell.world import load_world

    cell = tmp_path / "cell.toml"
    cell.write_text(WORLD_CAM)
    world = load_world(cell)
    view = WorldView(world)
    frames = tmp_path / "frames"
    async with running_node("sim", "--port", "0", "--world", str(cell), "--time-scale", "5",
                            "--state-endpoint", "tcp://127.0.0.1:0", log_path=tmp_path / "sim.log") as sim:
        async with running_node("vision", "--source", "world", "--world", str(cell),
                                "--state-endpoint", sim.ready["state"], "--graph", "noop", "--policy", "after",
                                "--request-endpoint", "tcp://127.0.0.1:0", "--response-endpoint", "tcp://127.0.0.1:0",
                                "--save-frames", str(frames), log_path=tmp_path / "vision.log") as vis, \
                Subscriber(sim.ready["state"], topics=[WORLD_STATE_TOPIC]) as sub, \
                RobotClient(sim.ready["host"], int(sim.ready["port"])) as robot, \
                Communicator(vis.ready["request"], vis.ready["response"], timeout_s=5.0) as comm:

            async def seen_where_published() -> np.ndarray:
                state = await next_world(sub)
                resp = await comm.request("VisionRequest", {})
                assert "error" not in resp.attributes and resp.attributes["camera"] == "world", resp.attributes
                png = frames / f"world_{int(resp.attributes['frame_seq']):06d}.png"
                async with asyncio.timeout(5.0):  # the recorder renames the PNG into place on its own thread
                    while not png.exists():
                        await asyncio.sleep(0.01)
                found = marker_in(png, 2)
                want = view.project(view.marker_corners_mm(world.part(5), state.part(5)))
                assert np.abs(found - want).max() < 1.0, (found, want)
                return found

            before = await seen_where_published()
            await robot.cmdexec(MoveToS(Pose(480.0, 0.0, TABLE_Z + 20.0, 0.0, 180.0, 0.0)), CloseHand(),
                                MoveToS(Pose(400.0, 150.0, TABLE_Z + 20.0, 0.0, 180.0, 0.0)), OpenHand(),
                                MoveToS(Pose(480.0, 0.0, TABLE_Z + 300.0, 0.0, 180.0, 0.0)), Break())
            await world_when(sub, 5, lambda p: not p.grasped and abs(p.pose.y - 150.0) < 0.01)
            after = await seen_where_published()
            assert np.linalg.norm(after.mean(axis=0) - before.mean(axis=0)) > 100, "the marker moved in the image"


@pytest.mark.timeout(90)
async def test_the_recording_draws_the_parts_in_3d_and_the_world_cameras_view(tmp_path):
    """A run recording following a sim with a world: run.rrd holds the table, each part's shape and its frame
    over time (following the tool while grasped), the world's events (the drop as an ERROR) and the camera's
    view; the same entities a live viewer gets."""
    from aioadept.record.live import RunRecording
    from aioadept.record.read import read_rrd
    from aioadept.cell.world import load_world

    cell = tmp_path / "cell.toml"
    cell.write_text(WORLD_CAM)
    world = load_world(cell)
    async with running_node("sim", "--port", "0", "--world", str(cell), "--time-scale", "5",
                            "--state-endpoint", "tcp://127.0.0.1:0", log_path=tmp_path / "sim.log") as sim:
        async with RunRecording(tmp_path / "run.rrd", state_endpoint=sim.ready["state"], world=world), \
                Subscriber(sim.ready["state"], topics=[WORLD_STATE_TOPIC]) as sub, \
                RobotClient(sim.ready["host"], int(sim.ready["port"])) as robot:
            # the carry at 5 %: about 0.4 s at this time scale, so the recording's 25 Hz draws it rising even on a
            # loaded machine (at 100 % it lasted a few tens of ms and a late sample could miss it)
            await robot.cmdexec(MoveToS(Pose(480.0, 0.0, TABLE_Z + 20.0, 0.0, 180.0, 0.0)), CloseHand(),
                                SetSpeed(5), MoveToS(Pose(400.0, 150.0, TABLE_Z + 100.0, 0.0, 180.0, 0.0)),
                                OpenHand())
            await world_when(sub, 5, lambda p: p.dropped)
            await next_world(sub)  # one more sample: the recording's subscriber has seen the drop too
    rows = read_rrd(tmp_path / "run.rrd")
    assert {"/world/table", "/world/feeder", "/world/parts/5", "/world/camera", "/world/camera/image",
            "/messages/world"} <= set(rows)
    part = rows["/world/parts/5"]
    assert any("Cylinders3D:radii" in r for r in part), "the cylinder's shape"
    zs = [r["Transform3D:translation"][0][2] for r in part if r.get("Transform3D:translation")]
    # it rose with the tool (up to +80: the grip is 20 mm above its bottom; samples drawn at 25 Hz) and lies on
    # the table again
    assert zs[0] == pytest.approx(TABLE_Z, abs=0.01) and zs[-1] == pytest.approx(TABLE_Z, abs=0.01)
    assert TABLE_Z + 40.0 < max(zs) <= TABLE_Z + 80.01
    logs = [(r["TextLog:level"][0], r["TextLog:text"][0]) for r in rows["/messages/world"]]
    assert any(level == "ERROR" and "dropped" in text for level, text in logs), logs
    images = [r for r in rows["/world/camera/image"] if any(k.startswith("EncodedImage:") for k in r)]
    assert len(images) >= 2, "the camera's view at the start and at least at the grasp and the drop"
