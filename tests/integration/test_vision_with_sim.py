"""The paper's experiment end to end: ``aioadept sim`` and ``aioadept vision`` as subprocesses, the test as the
MasterControlNode (RobotClient over TCP + Communicator over ZeroMQ): init_move, then MoveToolZ(+2 mm) steps with a
sharpness request after each. The virtual camera follows the sim's robot state stream; the sharpness must peak on
the configured focal plane (20 mm = 10 steps ahead)."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest

from aioadept import MoveJoints, MoveRelJoints, MoveRelTool, MoveToolZ, SetSpeed
from aioadept.bus.communicator import Communicator
from aioadept.client import RobotClient
from aioadept.testing.nodes import running_node


@contextlib.asynccontextmanager
async def node(log_path, command: str, *args: str):
    """A node subprocess (``python -m aioadept COMMAND ARGS``); yields its READY fields; must exit cleanly."""
    async with running_node(command, *args, log_path=log_path) as n:
        yield n.ready


@pytest.mark.timeout(60)
async def test_focus_sweep_through_sim_and_vision_peaks_on_the_focal_plane(tmp_path):
    async with node(tmp_path / "sim.log", "sim", "--port", "0", "--time-scale", "10",
                    "--state-endpoint", "tcp://127.0.0.1:0") as sim:
        async with node(tmp_path / "vision.log", "vision", "--state-endpoint", sim["state"],
                        "--request-endpoint", "tcp://127.0.0.1:0", "--response-endpoint", "tcp://127.0.0.1:0",
                        "--policy", "after", "--fps", "20", "--seed", "5") as vis:
            async with RobotClient(sim["host"], int(sim["port"])) as robot, \
                    Communicator(vis["request"], vis["response"], timeout_s=5.0) as comm:
                await robot.cmdexec(MoveJoints([0, -90, 180, 0, 90, 0]), MoveRelJoints([-90, 60, 30, -90, 0, 0]),
                                    MoveRelTool([40, -25, 185, 0, 0, 0]), MoveRelJoints([0, 0, 0, 0, 0, 1.5]))
                sharpness = []
                for _ in range(14):
                    resp = await comm.request("VisionRequest", {})
                    assert "error" not in resp.attributes, resp.attributes
                    sharpness.append(resp.attributes["sharpness"])
                    await robot.cmdexec_joined(SetSpeed(25), MoveToolZ(2.0))
    assert int(np.argmax(sharpness)) == 10, sharpness
    # The paper's stop rule (first decrease) fires one step after the peak.
    assert next(i for i in range(1, len(sharpness)) if sharpness[i] < sharpness[i - 1]) == 11
    assert sharpness[10] > 4 * sharpness[0]
