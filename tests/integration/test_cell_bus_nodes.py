"""Nodes started from the cell file itself: ``aioadept sim|vision|state --config CELL.toml`` take the
file's ``[bus]`` table (transport, cell, router) and put their streams on the keys the demo's application uses, the
command line winning over the file; ``aioadept state`` relays onto Zenoh with ``--transport zenoh``.

Real processes (``python -m aioadept``), real TCP and Zenoh on 127.0.0.1, each test with a hard time cap. The Zenoh
ones skip, with the reason, without the [zenoh] extra; their router runs in this test process
(``bustransports.start_zenoh_router``), so the cell files say ``start_router = false``.
"""

from __future__ import annotations

import asyncio
import importlib.util
import itertools
import json
import os
import subprocess
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

import pytest

from aioadept.ports import free_port
from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.geometry import Pose
from aioadept.protocol.statestream import StateSample, encode_state_line
from aioadept.testing.nodes import running_node

from bustransports import start_zenoh_router
from rawtcp import raw_server

AIOADEPT = [sys.executable, "-m", "aioadept"]
NO_ZENOH = importlib.util.find_spec("zenoh") is None
needs_zenoh = pytest.mark.skipif(NO_ZENOH, reason="the [zenoh] extra (eclipse-zenoh) is not installed")

_cells = itertools.count()


def cell_name() -> str:
    """A cell of its own per test: no token or sample of another test's nodes is ever seen."""
    return f"cfg{os.getpid()}x{next(_cells)}"


def zenoh_cell_file(path: Path, cell: str, router: str, **robot: object) -> Path:
    """A cell whose nodes run elsewhere (start_sim/start = false) on Zenoh, every endpoint written as a ZeroMQ
    address that is NOT the default: a node that ignored [bus] would bind it instead of the cell's key."""
    rows = "".join(f"{k} = {json.dumps(v)}\n" for k, v in robot.items())
    path.write_text(
        f'[robot]\nhost = "127.0.0.1"\nstart_sim = false\nstate_endpoint = "tcp://127.0.0.1:{free_port()}"\n{rows}'
        f'[vision]\nstart = false\nrequest_endpoint = "tcp://127.0.0.1:{free_port()}"\n'
        f'response_endpoint = "tcp://127.0.0.1:{free_port()}"\nfocus_offset_mm = 20.0\n'
        f'[bus]\ntransport = "zenoh"\ncell = "{cell}"\nzenoh_router = "{router}"\nstart_router = false\n')
    return path


# ------------------------------------------------------------------------------- the options each node resolves
# (no Zenoh session is opened here: sim's and state's parse_args stop before configuring one)


def test_sim_and_state_take_the_bus_table_and_the_command_line_wins(tmp_path):
    from aioadept.cli import sim, state

    path = zenoh_cell_file(tmp_path / "cell.toml", "c1", "tcp/127.0.0.1:7601")
    for mod in (sim, state):
        a = mod.parse_args(mod.build_parser(), ["--config", str(path)])
        assert (a.transport, a.cell, a.zenoh_connect, a.zenoh_listen, a.state_endpoint) == (
            "zenoh", "c1", "tcp/127.0.0.1:7601", None, "zenoh:aioadept/c1/sim/state"), mod.__name__
        # --transport zeromq: the file's own endpoint, and none of its Zenoh options
        a = mod.parse_args(mod.build_parser(), ["--config", str(path), "--transport", "zeromq"])
        assert a.transport == "zeromq" and a.cell is None and a.zenoh_connect is None
        assert a.state_endpoint.startswith("tcp://127.0.0.1:")
        # --cell renames the keys; --zenoh-listen replaces the file's router (not both); an endpoint given is kept
        a = mod.parse_args(mod.build_parser(), ["--config", str(path), "--cell", "c2", "--zenoh-listen",
                                                "tcp/127.0.0.1:7602"])
        assert (a.cell, a.zenoh_connect, a.zenoh_listen, a.state_endpoint) == (
            "c2", None, "tcp/127.0.0.1:7602", "zenoh:aioadept/c2/sim/state")
        a = mod.parse_args(mod.build_parser(), ["--config", str(path), "--state-endpoint", "tcp://127.0.0.1:7603"])
        assert (a.transport, a.state_endpoint) == ("zenoh", "tcp://127.0.0.1:7603")
    assert state.parse_args(state.build_parser(), ["--config", str(path)]).robot == "127.0.0.1:1236"


def test_a_zeromq_file_leaves_the_nodes_on_zeromq_unless_the_command_line_says_zenoh(tmp_path):
    from aioadept.cli import sim

    path = tmp_path / "cell.toml"
    path.write_text('[robot]\nstate_endpoint = "tcp://127.0.0.1:7611"\n[bus]\ncell = "c3"\n'
                    'zenoh_router = "tcp/127.0.0.1:7612"\n')
    a = sim.parse_args(sim.build_parser(), ["--config", str(path)])
    assert (a.transport, a.cell, a.zenoh_connect, a.state_endpoint) == ("zeromq", None, None, "tcp://127.0.0.1:7611")
    # as `aioadept demo --config FILE --transport zenoh`: the file's cell and router, its endpoint on the cell's key
    a = sim.parse_args(sim.build_parser(), ["--config", str(path), "--transport", "zenoh"])
    assert (a.transport, a.cell, a.zenoh_connect, a.state_endpoint) == (
        "zenoh", "c3", "tcp/127.0.0.1:7612", "zenoh:aioadept/c3/sim/state")


# ------------------------------------------------------------------------------------------ mistakes: one line


@pytest.mark.timeout(120)
@pytest.mark.parametrize("command", ["sim", "vision", "state"])
@pytest.mark.parametrize("table, key", [
    ('transport = "nanomsg"', "transport"),
    ('transport = "zenoh"\ncell = "a/b"', "cell"),
    ('transport = "zenoh"\nzenoh_router = "127.0.0.1:7447"', "zenoh_router"),
    ('transport = "zenoh"\nzenoh_router = "tcp/127.0.0.1:0"', "zenoh_router"),  # only a starter can pick a port
])
def test_a_bad_bus_table_is_one_line_naming_the_file_and_the_key_with_exit_2(tmp_path, command, table, key):
    path = tmp_path / "cell.toml"
    path.write_text(f"[bus]\n{table}\n")
    proc = subprocess.run([*AIOADEPT, command, "--config", str(path)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert lines[0].startswith(f"aioadept {command}: {path} [bus]: {key}"), lines[0]
    assert proc.stdout == ""


@pytest.mark.timeout(60)
@pytest.mark.parametrize("argv, text", [
    (["--transport", "zenoh", "--cell", "a/b"], "--cell 'a/b': one key chunk"),
    (["--transport", "zenoh", "--zenoh-connect", "tcp/127.0.0.1"], "tcp/HOST:PORT"),
    (["--node", "r1"], "--node needs --transport zenoh"),
])
def test_state_transport_mistakes_are_one_line_with_exit_2(argv, text):
    proc = subprocess.run([*AIOADEPT, "state", *argv], capture_output=True, text=True, timeout=50)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and text in lines[0], proc.stderr


# ------------------------------------------------------------------------------------- the relay, on both sides


@asynccontextmanager
async def controller_state_port(z0: float = 710.0) -> AsyncIterator[int]:
    """A V+ state port (rsstate.V2's S1 lines) on 127.0.0.1 sending a sample every 20 ms, z falling 0.5 mm each,
    until closed; yields its port."""

    async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        for i in itertools.count():
            writer.write(encode_state_line(StateSample(1.0 + i * 0.02, (0.0, -90.0, 180.0, 0.0, 90.0, 0.0),
                                                       Pose(480.0, 0.0, z0 - 0.5 * i, 0.0, 180.0, 0.0))))
            await writer.drain()
            await asyncio.sleep(0.02)

    async with raw_server(serve) as port:
        yield port


async def states(endpoint: str, n: int, timeout_s: float = 15.0) -> list[RobotState]:
    from aioadept.bus.pubsub import Subscriber

    async with Subscriber(endpoint, topics=[ROBOT_STATE_TOPIC]) as sub:
        return [RobotState.from_bytes((await asyncio.wait_for(sub.recv(), timeout_s))[1]) for _ in range(n)]


@pytest.mark.timeout(60)
async def test_state_from_a_zenoh_cell_file_given_zeromq_on_the_command_line_publishes_on_zeromq(tmp_path):
    path = zenoh_cell_file(tmp_path / "cell.toml", "zq", "tcp/127.0.0.1:9")  # a router that is never asked for
    async with controller_state_port() as port:
        async with running_node("state", "--config", str(path), "--transport", "zeromq", "--robot",
                                f"127.0.0.1:{port}", "--state-endpoint", "tcp://127.0.0.1:0",
                                log_path=tmp_path / "state.log") as relay:
            assert relay.ready["state"].startswith("tcp://127.0.0.1:") and relay.ready["source"] == f"127.0.0.1:{port}"
            got = await states(relay.ready["state"], 3)
    zs = [s.pose.z for s in got]
    assert zs == sorted(zs, reverse=True) and all(s.joints_deg == pytest.approx((0, -90, 180, 0, 90, 0)) for s in got)


@needs_zenoh
@pytest.mark.timeout(90)
@pytest.mark.parametrize("how", ["command line", "cell file"])
async def test_state_relays_a_controller_onto_the_cells_zenoh_key_and_declares_itself(tmp_path, how):
    from aioadept.bus.presence import NodeWatcher

    router, cell = start_zenoh_router(), cell_name()
    if how == "command line":
        argv = ["--transport", "zenoh", "--cell", cell, "--zenoh-connect", router]
    else:
        argv = ["--config", str(zenoh_cell_file(tmp_path / "cell.toml", cell, router))]
    async with NodeWatcher(cell) as watcher, controller_state_port() as port:
        async with running_node("state", *argv, "--robot", f"127.0.0.1:{port}",
                                log_path=tmp_path / "state.log") as relay:
            # where the sim of this cell would publish, and where the demo's application and the vision node look
            assert relay.ready["state"] == f"zenoh:aioadept/{cell}/sim/state"
            await watcher.wait_for("state", True, timeout_s=2.0)
            got = await states(relay.ready["state"], 5)
        await watcher.wait_for("state", False, timeout_s=2.0)  # a clean stop undeclares it
    ts, zs = [s.t_s for s in got], [s.pose.z for s in got]
    assert ts == sorted(ts) and len(set(ts)) == 5 and zs == sorted(zs, reverse=True)
    # each sample is the controller's line: z = 710 - 0.5 mm per 20 ms of its clock
    assert all(s.pose.z == pytest.approx(710.0 - 0.5 * round((s.t_s - 1.0) / 0.02)) for s in got)


# ------------------------------------------------------------ a whole cell, every node from the one cell file


@needs_zenoh
@pytest.mark.timeout(150)
async def test_sim_and_vision_from_a_zenoh_cell_file_serve_the_demos_application_asking_by_zenoh_queries(tmp_path):
    import zenoh

    from aioadept.bus import zenoh as zb
    from aioadept.bus.presence import NodeWatcher

    router, cell = start_zenoh_router(), cell_name()
    port, stop_port = free_port(), free_port()
    path = zenoh_cell_file(tmp_path / "cell.toml", cell, router, port=port, stop_port=stop_port, time_scale=20.0)
    with path.open("a") as fh:
        fh.write('zenoh_queries = true\n'  # (the [bus] table is the file's last so far)
                 f'[focus]\ndelta_z_mm = 2.0\napproach_speed = 25\n'
                 f'[run]\nout_dir = "{tmp_path / "runs"}"\nanalyze = false\nrecord = false\n')
    published: list[bytes] = []  # answers published on the response key (with zenoh_queries: none, all are replies)
    watch_answers = zb.session().declare_subscriber(f"aioadept/{cell}/vision/response",
                                                    zenoh.handlers.Callback(lambda s: published.append(b"")))
    async with NodeWatcher(cell) as watcher:
        async with running_node("sim", "--config", str(path), log_path=tmp_path / "sim.log") as sim, \
                   running_node("vision", "--config", str(path), log_path=tmp_path / "vision.log") as vision:
            # the file's tcp:// endpoints became the cell's keys; the nodes joined the file's router
            assert sim.ready["state"] == f"zenoh:aioadept/{cell}/sim/state" and sim.ready["port"] == str(port)
            assert vision.ready["request"] == f"zenoh:aioadept/{cell}/vision/request"
            assert vision.ready["response"] == f"zenoh:aioadept/{cell}/vision/response"
            assert vision.ready["state"] == sim.ready["state"]
            await watcher.wait_for("sim", True, timeout_s=2.0)
            await watcher.wait_for("vision", True, timeout_s=2.0)
            # the demo's application, from the same file, runs against them (start_sim/start = false)
            demo = await asyncio.create_subprocess_exec(*AIOADEPT, "demo", "--config", str(path),
                                                        stdout=asyncio.subprocess.PIPE,
                                                        stderr=asyncio.subprocess.STDOUT)
            try:
                out, _ = await asyncio.wait_for(demo.communicate(), 120)
            finally:
                if demo.returncode is None:
                    demo.kill()
                    await demo.wait()
            assert demo.returncode == 0, out.decode(errors="replace")[-3000:]
    watch_answers.undeclare()
    assert published == []  # every answer was the reply to its query
    (run_dir,) = (tmp_path / "runs").iterdir()
    focus = json.loads((run_dir / "focus.json").read_text())
    # The focal plane 20 mm beyond the approach pose is step 10 of 2 mm: the virtual camera followed the sim's
    # state through the cell's key, and answered the application's requests on the cell's keys.
    assert focus["peak_index"] == 10 and focus["peak_offset_mm"] == pytest.approx(20.0), focus
    assert max(focus["sharpness"]) == focus["sharpness"][10] > 4 * focus["sharpness"][0], focus
