"""What only the Zenoh transport has: node presence through liveliness, seen within 1 s when a
real node process is killed and restarted; the session's isolation (no multicast scouting, no gossip, loopback
only); the cell file's ``[bus]`` table; and what the transport refuses. The bus behaviour both transports share is
tested by the ``bus``-parametrised modules (test_bus_communicator.py, test_bus_pubsub.py, ...)."""

from __future__ import annotations

import asyncio
import importlib.util
import signal
import subprocess
import sys
import time

import pytest

from aioadept.apps.cell import sim_argv, vision_argv
from aioadept.cell.config import CellConfig
from aioadept.cell.bus import with_transport
from aioadept.bus import Communicator, Publisher
from aioadept.errors import BusError
from aioadept.apps.processes import NodeProcess
from aioadept.testing.nodes import running_node

from bustransports import start_zenoh_router

pytestmark = pytest.mark.skipif(importlib.util.find_spec("zenoh") is None,
                                reason="the [zenoh] extra (eclipse-zenoh) is not installed")

CELL = "livetest"


@pytest.fixture
def router() -> str:
    return start_zenoh_router()


@pytest.mark.timeout(90)
async def test_a_killed_vision_node_is_seen_gone_within_1_s_and_seen_again_within_1_s_of_its_restart(router, tmp_path):
    from aioadept.bus.presence import NodeWatcher

    argv = ("--transport", "zenoh", "--zenoh-connect", router, "--cell", CELL, "--state-endpoint", "none",
            "--graph", "noop")
    async with NodeWatcher(CELL) as watcher:
        assert "vision" not in watcher.alive
        node = NodeProcess("vision", ["vision", *argv], log_path=tmp_path / "vision1.log")
        await node.start()
        try:
            assert node.ready["request"] == f"zenoh:aioadept/{CELL}/vision/request"
            await watcher.wait_for("vision", True, timeout_s=1.0)  # declared as it printed READY
            async with Communicator(node.ready["request"], node.ready["response"], timeout_s=5.0) as comm:
                assert "error" not in (await comm.request("VisionRequest", {})).attributes
                # kill -9: no goodbye from the node; the router sees its link drop.
                node.proc.send_signal(signal.SIGKILL)
                t_kill = time.monotonic()
                await watcher.wait_for("vision", False, timeout_s=1.0)
                gone_s = time.monotonic() - t_kill
                await node.proc.wait()
                # The same command line again: no configuration changes anywhere.
                async with running_node("vision", *argv, log_path=tmp_path / "vision2.log",
                                        expect_clean_exit=False):
                    t_ready = time.monotonic()
                    await watcher.wait_for("vision", True, timeout_s=1.0)
                    seen_s = time.monotonic() - t_ready
                    # ... and the application's same Communicator is served by the new node.
                    assert "error" not in (await comm.request("VisionRequest", {})).attributes
                await watcher.wait_for("vision", False, timeout_s=1.0)  # a clean stop undeclares it too
        finally:
            await node.stop()
    assert gone_s < 1.0 and seen_s < 1.0


@pytest.mark.timeout(20)
async def test_the_watcher_reports_appear_and_vanish_events_in_order(router):
    from aioadept.bus import zenoh as zb
    from aioadept.bus.presence import NodeWatcher

    async with NodeWatcher("evtest") as watcher:
        token = zb.session().liveliness().declare_token("aioadept/evtest/cam1")
        token.undeclare()
        events = [await asyncio.wait_for(anext(aiter(watcher)), 2.0) for _ in range(2)]
    assert [(e.cell, e.node, e.alive) for e in events] == [("evtest", "cam1", True), ("evtest", "cam1", False)]


@pytest.mark.timeout(10)
def test_the_session_config_has_no_multicast_scouting_no_gossip_and_loopback_endpoints():
    from aioadept.bus.zenoh import DEFAULT_ROUTER, ZenohOptions

    for opts in (ZenohOptions(), ZenohOptions.router(), ZenohOptions.client("tcp/127.0.0.1:9999")):
        cfg = opts.config()
        assert cfg.get_json("scouting/multicast/enabled") == "false"
        assert cfg.get_json("scouting/gossip/enabled") == "false"
        for loc in (*opts.connect, *opts.listen):
            assert loc.startswith("tcp/127.0.0.1:")
    assert DEFAULT_ROUTER == "tcp/127.0.0.1:7447"
    with pytest.raises(BusError, match="tcp/HOST:PORT"):
        ZenohOptions.client("udp/127.0.0.1:7447")
    with pytest.raises(BusError, match="router needs a listen endpoint"):
        ZenohOptions(mode="router", connect=(), listen=())


@pytest.mark.timeout(10)
async def test_curve_and_bad_keys_are_refused_with_the_reason(router):
    from aioadept.bus.security import CurveClient, CurveKeyPair

    keys = CurveKeyPair.generate()
    with pytest.raises(BusError, match="CURVE is ZeroMQ's"):
        Publisher("zenoh:aioadept/t/x/y", curve=CurveClient(keys, keys.public))
    with pytest.raises(BusError, match="chunk"):
        Publisher("zenoh:aioadept/t/*/y")  # nobody publishes on a wildcard
    with pytest.raises(BusError, match="chunk"):
        Publisher("zenoh:aioadept//y")


@pytest.mark.timeout(10)
def test_a_zenoh_cell_puts_every_stream_on_the_cells_keys_and_starts_its_nodes_with_the_router():
    cfg = CellConfig.from_dict({"bus": {"transport": "zenoh", "cell": "c7", "zenoh_router": "tcp/127.0.0.1:7500"},
                                "robot": {"state_endpoint": "tcp://127.0.0.1:5560"}})
    z = with_transport(cfg)
    assert (z.robot.state_endpoint, z.vision.request_endpoint, z.vision.response_endpoint) == (
        "zenoh:aioadept/c7/sim/state", "zenoh:aioadept/c7/vision/request", "zenoh:aioadept/c7/vision/response")
    tail = ["--transport", "zenoh", "--cell", "c7", "--zenoh-connect", "tcp/127.0.0.1:7500"]
    for argv in (sim_argv(z), vision_argv(z)):
        assert argv[argv.index("--transport"):argv.index("--transport") + 6] == tail
    assert with_transport(CellConfig()) == CellConfig()  # ZeroMQ: untouched, and no --transport for its nodes
    assert "--transport" not in sim_argv(CellConfig()) + vision_argv(CellConfig())


@pytest.mark.timeout(30)
@pytest.mark.parametrize("table, key", [
    ('transport = "nanomsg"', "transport"),
    ('transport = "zenoh"\ncell = "a/b"', "cell"),
    ('transport = "zenoh"\nzenoh_router = "127.0.0.1:7447"', "zenoh_router"),
    ('transports = "zenoh"', "transports"),
])
def test_a_bad_bus_table_is_one_line_naming_the_file_and_the_key(tmp_path, table, key):
    path = tmp_path / "cell.toml"
    path.write_text(f"[bus]\n{table}\n")
    proc = subprocess.run([sys.executable, "-m", "aioadept", "demo", "--config", str(path)], capture_output=True,
                          text=True, timeout=25)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and key in lines[0] and "Traceback" not in proc.stderr


@pytest.mark.timeout(30)
@pytest.mark.parametrize("argv, text", [
    (["--cell", "x"], "--cell needs --transport zenoh"),
    (["--transport", "zenoh", "--zenoh-connect", "tcp/127.0.0.1"], "tcp/HOST:PORT"),
    (["--transport", "zenoh", "--cell", "a/b"], "--cell"),
])
def test_node_transport_mistakes_are_one_line(argv, text):
    proc = subprocess.run([sys.executable, "-m", "aioadept", "sim", "--port", "0", *argv], capture_output=True,
                          text=True, timeout=25)
    assert proc.returncode == 2 and text in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.timeout(60)
async def test_the_v_plus_backend_publishes_its_state_on_the_cells_key_and_declares_itself(router):
    from pathlib import Path

    from aioadept.bus import Subscriber
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.presence import NodeWatcher

    vplus = Path(__file__).resolve().parents[2] / "vplus"
    files = [str(vplus / f) for f in ("rsconfig.V2", "rserver.V2", "rsskills.V2", "rsstate.V2")]
    async with NodeWatcher("vptest") as watcher:
        async with running_node("sim", "--vplus", *files, "--run", "rs.main", "--map-port", "1234=0",
                                "--map-port", "1235=0", "--transport", "zenoh", "--zenoh-connect", router,
                                "--cell", "vptest", expect_clean_exit=False) as node:
            assert node.ready["state"] == "zenoh:aioadept/vptest/sim/state"
            await watcher.wait_for("sim", True, timeout_s=1.0)
            async with Subscriber(node.ready["state"], topics=[ROBOT_STATE_TOPIC]) as sub:
                topic, payload = await asyncio.wait_for(sub.recv(), 10)
            assert topic == ROBOT_STATE_TOPIC
            assert len(RobotState.from_bytes(payload).joints_deg) == 6
        await watcher.wait_for("sim", False, timeout_s=1.0)


def _open_fds() -> int:
    import os

    return len(os.listdir("/proc/self/fd"))


@pytest.mark.timeout(60)
async def test_opening_and_closing_many_communicators_and_responders_leaves_no_descriptor_behind(router):
    # Each reading Zenoh socket owns an eventfd the loop watches (its wake-up): closing must give it back,
    # for a reader (Communicator, Responder) and for an awaited recv (Subscriber) alike.
    from aioadept.bus import Responder, Subscriber

    async def one(i: int) -> None:
        key = f"zenoh:aioadept/fdtest/{i}"
        async with Responder(f"{key}/req", f"{key}/resp", lambda t, rid, a: {"i": i}):
            async with Communicator(f"{key}/req", f"{key}/resp", timeout_s=5.0) as comm:
                assert (await comm.request("VisionRequest")).attributes == {"i": i}
        async with Subscriber(f"{key}/state") as sub, Publisher(f"{key}/state", bind=False) as pub:
            got = asyncio.ensure_future(sub.recv())
            while not got.done():  # until the subscription has reached the publisher's side
                pub.publish_nowait("robot.state", b"%d" % i)
                await asyncio.wait({got}, timeout=0.02)
            assert got.result() == (b"robot.state", b"%d" % i)

    await one(-1)  # the session's own descriptors are opened by now
    before = _open_fds()
    for i in range(40):
        await one(i)
    assert _open_fds() - before <= 2  # allowing for a socket Zenoh may hold briefly


@pytest.mark.timeout(30)
async def test_a_burst_larger_than_a_read_batch_is_delivered_whole_and_in_order(router):
    from aioadept.bus.sockets import READ_BATCH, SocketReader, make_socket
    import zmq

    key = "zenoh:aioadept/bursttest/a"
    got: list[bytes] = []
    batches: list[int] = []
    sub = make_socket(zmq.SUB, endpoint=key, hwm=10 * READ_BATCH, topics=(b"",))
    sub.declare()
    reader = SocketReader(sub, lambda b: (batches.append(len(b)), got.extend(f[-1] for f in b)), name="burst")
    reader.start()
    n = 3 * READ_BATCH + 7
    try:
        async with Publisher(key, bind=False) as pub:
            await asyncio.sleep(0.2)  # the subscription reaches the publisher's side
            for i in range(n):
                pub.send_nowait(b"%d" % i)
            deadline = time.monotonic() + 10
            while len(got) < n and time.monotonic() < deadline:
                await asyncio.sleep(0.01)
    finally:
        await reader.stop()
        sub.close()
    assert got == [b"%d" % i for i in range(n)]
    assert max(batches) <= READ_BATCH


@pytest.mark.timeout(30)
async def test_a_socket_closed_from_another_thread_while_its_loop_reads_stops_quietly(router, caplog):
    import threading

    import zmq
    from aioadept.bus.sockets import SocketReader, make_socket

    key = "zenoh:aioadept/closetest/a"
    before = _open_fds()
    got: list[bytes] = []
    sub = make_socket(zmq.SUB, endpoint=key, topics=(b"",))
    sub.declare()
    reader = SocketReader(sub, lambda b: got.extend(f[-1] for f in b), name="closing")
    reader.start()
    async with Publisher(key, bind=False) as pub:
        await asyncio.sleep(0.2)
        pub.send_nowait(b"before")
        deadline = time.monotonic() + 5
        while not got and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        closer = threading.Thread(target=sub.close)
        closer.start()
        await asyncio.to_thread(closer.join)
        for _ in range(20):  # a publication after the close reaches nobody and breaks nothing
            pub.send_nowait(b"after")
        await asyncio.sleep(0.2)  # the loop runs the eventfd's removal that the other thread handed it
    await reader.stop()
    assert got == [b"before"]
    assert _open_fds() <= before
    assert not [r for r in caplog.records if r.levelno >= 30]
