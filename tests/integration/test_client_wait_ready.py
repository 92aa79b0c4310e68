"""``RobotClient.wait_ready()``: the app starts before the controller, over real TCP on 127.0.0.1.

The client begins waiting while nothing listens on the port (connections refused), then a real server starts
there: in-process (SimServer) and as a separate process (``aioadept sim --vplus``, the shipped V+ server on the
emulator, whose port is open a while before its reader answers). A port where a peer accepts and never answers
is retried too, and the wait ends with ConnectError naming the last failure when the time is up.
"""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from aioadept.client import RobotClient
from aioadept.errors import ConnectError
from aioadept.sim.server import SimOptions, SimServer
from aioadept.testing.nodes import running_node
from aioadept.ports import free_port

VPLUS = Path(__file__).resolve().parents[2] / "vplus"


@pytest.mark.timeout(30)
async def test_waits_until_a_server_started_later_answers_hello():
    port = free_port()
    loop = asyncio.get_running_loop()
    robot = RobotClient("127.0.0.1", port, connect_timeout_s=1.0)
    t0 = loop.time()
    waiting = asyncio.create_task(robot.wait_ready(20.0))
    await asyncio.sleep(0.8)
    assert not waiting.done(), "nothing listens yet: it must still be waiting"
    async with SimServer(SimOptions(port=port, state_endpoint=None, instant=True)):
        version, name = await asyncio.wait_for(waiting, 10.0)
        took = loop.time() - t0
        assert (version, name.split()[0]) == (1, "aioadept-sim")
        assert 0.8 <= took < 3.0, "backoff is capped at 1 s: ready within about a second of the server"
        assert robot.connected
        async with robot:                # the connection it made is the one the app goes on with
            here = await robot.here()
            assert here.z > 0
        assert not robot.connected


@pytest.mark.timeout(60)
async def test_waits_for_the_v_plus_server_process(tmp_path):
    port = free_port()
    robot = RobotClient("127.0.0.1", port)
    waiting = asyncio.create_task(robot.wait_ready(45.0))
    await asyncio.sleep(0.3)
    files = [str(VPLUS / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]
    async with running_node("sim", "--vplus", *files, "--run", "rs.main", "--map-port", f"1234={port}",
                            "--map-port", "1235=0", "--state-endpoint", "none", log_path=tmp_path / "sim.log", ready_timeout_s=45):
        version, name = await asyncio.wait_for(waiting, 40.0)
        assert (version, name) == (1, "aioadept-vplus 0.1.0")
        st = await robot.status()
        assert not st.moving
        await robot.close()


@pytest.mark.timeout(30)
async def test_a_silent_peer_is_retried_and_the_wait_ends_with_connect_error():
    accepted = 0

    async def silent(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        nonlocal accepted
        accepted += 1
        await reader.read()          # never answers; closes when the client gives up
        writer.close()

    server = await asyncio.start_server(silent, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    loop = asyncio.get_running_loop()
    robot = RobotClient("127.0.0.1", port, connect_timeout_s=1.0)
    t0 = loop.time()
    try:
        with pytest.raises(ConnectError, match=r"not ready within 5 s .*attempts; last: .*hello"):
            await robot.wait_ready(5.0)
    finally:
        server.close()
    took = loop.time() - t0
    assert 4.9 <= took < 7.0
    assert accepted >= 2, "each attempt that got no hello answer was closed and tried again"
    assert not robot.connected


@pytest.mark.parametrize("bad", [0, -1, float("nan"), float("inf")])
async def test_bad_timeouts_are_refused_before_anything(bad):
    with pytest.raises(ValueError, match="timeout_s"):
        await RobotClient("127.0.0.1", 1).wait_ready(bad)
