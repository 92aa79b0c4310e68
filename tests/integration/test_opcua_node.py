"""``aioadept opcua`` read by an independent OPC UA stack: node-opcua's client (npm ``node-opcua-client``, pinned with
its tree in tests/integration/opcua_node/package-lock.json), run by pytest as a node script against real processes
(``aioadept sim``, ``aioadept opcua`` on 127.0.0.1).

The script finds the MotionDeviceSystem from the Objects folder by its type definition in the Robotics namespace,
reads EmergencyStop and OperationalMode, and subscribes to the six ActualPosition values while the sim moves; they
must end at ``here``'s joints within 0.01 deg. The client is installed by this module's set-up (``npm ci`` into
build/node-opcua, which git ignores) where node and npm exist; where they do not, the test is skipped with a warning
saying so.
"""

from __future__ import annotations

import asyncio
import importlib.util
import json
import os
import shutil
from pathlib import Path

import pytest

from aioadept.commands import Here, MoveJoints, SetSpeed

from npmtree import npm_tree
from opcuacell import TARGET, opcua_cell

pytestmark = pytest.mark.skipif(importlib.util.find_spec("asyncua") is None,
                                reason="the [opcua] extra (asyncua) is not installed")

HERE = Path(__file__).resolve().parent / "opcua_node"


@pytest.fixture(scope="module")
def node_client() -> Path:
    """The node script, with node-opcua installed beside it."""
    return npm_tree(HERE, "node-opcua", what="NODE-OPCUA INTEROP TEST") / "robot_client.mjs"


class Lines:
    """The script's JSON lines, read as they come."""

    def __init__(self, proc: asyncio.subprocess.Process) -> None:
        self.proc = proc
        self.items: list[dict] = []
        self.task = asyncio.create_task(self._read())

    async def _read(self) -> None:
        assert self.proc.stdout is not None
        async for raw in self.proc.stdout:
            if raw.startswith(b"{"):  # node-opcua writes its own warnings on stdout too
                self.items.append(json.loads(raw))

    async def first(self, key: str, timeout_s: float) -> dict:
        async def wait() -> dict:
            while True:
                for item in self.items:
                    if key in item:
                        return item
                if self.task.done():
                    raise AssertionError(f"the node script ended before {key!r}: {self.items}")
                await asyncio.sleep(0.02)
        return await asyncio.wait_for(wait(), timeout_s)


@pytest.mark.timeout(300)
async def test_node_opcua_finds_the_robot_by_type_and_sees_here_s_joints_at_rest(tmp_path, node_client) -> None:
    from aioadept.client import RobotClient

    async with opcua_cell(tmp_path) as cell:
        env = dict(os.environ, HOME=str(tmp_path), XDG_CONFIG_HOME=str(tmp_path / "config"))  # its PKI folder
        with open(tmp_path / "node.err", "wb") as err:
            proc = await asyncio.create_subprocess_exec(
                shutil.which("node"), str(node_client), cell.url, cwd=node_client.parent, env=env,
                stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE, stderr=err)
        lines = Lines(proc)
        try:
            found = await lines.first("found", 60)
            assert found["device"] == "Robot1" and found["axes"] == [f"Axis{i}" for i in range(1, 7)]
            assert found["emergencyStop"] == {"value": False, "status": "Good"}
            assert found["operationalMode"] == {"value": None, "status": "BadNotSupported"}
            assert (await lines.first("subscribed", 30))["subscribed"] == 6
            async with RobotClient("127.0.0.1", cell.robot_port) as robot:
                await robot.cmdexec(SetSpeed(100))
                await robot.cmdexec(MoveJoints(TARGET))  # with its break: acked at rest
                here = [float(j) for j in (await robot.cmdexec(Here())).messages[0].ack.extra[0].split(",")]

            def last() -> dict[int, dict]:
                return {item["axis"]: item for item in lines.items if "axis" in item}

            async def at_rest() -> None:
                while not (len(last()) == 6 and all(
                        v["status"] == "Good" and abs(v["value"] - here[i - 1]) <= 0.01 for i, v in last().items())):
                    await asyncio.sleep(0.02)

            await asyncio.wait_for(at_rest(), 10)
            assert max(abs(a - b) for a, b in zip(here, TARGET, strict=True)) < 0.01
            # It saw the arm on its way, not only where it ended.
            moving = [item for item in lines.items if item.get("axis") == 3 and abs(item["value"] - here[2]) > 0.1]
            assert moving, lines.items
        finally:
            assert proc.stdin is not None
            proc.stdin.close()
            try:
                code = await asyncio.wait_for(proc.wait(), 15)
            except TimeoutError:
                proc.kill()
                code = await proc.wait()
            lines.task.cancel()
        assert code == 0, (tmp_path / "node.err").read_text()[-3000:]
