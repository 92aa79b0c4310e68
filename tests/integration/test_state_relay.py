"""``StateRelay`` / ``aioadept state`` against a scripted state port over real TCP and ZeroMQ on 127.0.0.1: lines
split anywhere, lines it must skip, a controller that goes silent, and the command line's mistakes."""

from __future__ import annotations

import asyncio
import subprocess
import sys

import pytest

from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import Publisher, Subscriber
from aioadept.client.statestream import StateRelay
from aioadept.geometry import Pose
from aioadept.protocol.statestream import StateSample, encode_state_line

pytestmark = pytest.mark.timeout(30)


def line(t: float, z: float = 710.0, **kw) -> bytes:
    return encode_state_line(StateSample(t, (0.0, -90.0, 180.0, 0.0, 90.0, 0.0), Pose(480, 0, z, 0, 180, 0), **kw))


async def test_relays_good_lines_skips_the_rest_and_reconnects_when_the_port_goes_silent():
    connections: list[asyncio.StreamWriter] = []
    handlers: list[asyncio.Task] = []
    go_silent = asyncio.Event()

    async def controller(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        connections.append(writer)
        handlers.append(asyncio.current_task())
        if len(connections) == 1:
            data = (line(1.0) + b"S2 t=1 future=1\r\n" + b"S1 t=x j=1 p=2\r\n" + line(1.01, 700.0, moving=True)
                    + b"\r\n" + line(1.02, 690.0, moving=True, air=True))
            for i in range(0, len(data), 7):           # split anywhere: framing is the relay's job
                writer.write(data[i:i + 7])
                await writer.drain()
                await asyncio.sleep(0)
            await go_silent.wait()                      # then nothing, with the connection open
        else:
            writer.write(line(0.5))                     # a restarted controller: its clock starts again
        await reader.read()

    server = await asyncio.start_server(controller, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    pub = Publisher("tcp://127.0.0.1:0", bind=True)
    relay = StateRelay("127.0.0.1", port, pub, idle_timeout_s=0.5)
    try:
        async with Subscriber(pub.actual_endpoint, topics=[ROBOT_STATE_TOPIC]) as sub:
            await asyncio.sleep(0.2)                    # the SUB joins before the first publish (slow joiner)
            task = asyncio.create_task(relay.run())
            got = [RobotState.from_bytes((await asyncio.wait_for(sub.recv(), 5))[1]) for _ in range(3)]
            assert [s.t_s for s in got] == [1.0, 1.01, 1.02]
            assert [s.pose.z for s in got] == [710.0, 700.0, 690.0]
            assert [s.in_motion for s in got] == [False, True, True] and got[2].air
            assert relay.stats.skipped == 2 and relay.stats.published == 3
            # wall time = t + the smallest (receive time - t) so far: monotonic, and its offset never grows
            walls = [s.wall_time_s for s in got]
            offsets = [w - s.t_s for w, s in zip(walls, got, strict=True)]
            assert walls == sorted(walls) and offsets == sorted(offsets, reverse=True)
            # silent for longer than idle_timeout_s: the relay drops the connection and connects again
            again = RobotState.from_bytes((await asyncio.wait_for(sub.recv(), 5))[1])
            assert again.t_s == 0.5 and relay.stats.connections == 2
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
    finally:
        go_silent.set()
        for w in connections:
            w.close()
        server.close()
        if handlers:
            await asyncio.wait(handlers, timeout=2)
        pub.close()


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "aioadept", "state", *args], capture_output=True, text=True,
                          timeout=20)


@pytest.mark.parametrize("args, words", [
    (["--robot", "127.0.0.1:99999"], ["--robot", "127.0.0.1:99999", "HOST[:PORT]"]),
    (["--state-curve-allow", "x.key"], ["--state-curve-allow needs --state-curve-secret"]),
    (["--state-curve-secret", "/nonexistent.key_secret"], ["/nonexistent.key_secret"]),
])
def test_command_line_mistakes_are_one_line_with_exit_2(args, words):
    proc = run(*args)
    assert proc.returncode == 2
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert lines[0].startswith("aioadept state: ") and all(w in lines[0] for w in words), lines[0]


def test_an_endpoint_already_taken_is_one_line_with_exit_1():
    pub = Publisher("tcp://127.0.0.1:0", bind=True)
    try:
        proc = run("--robot", "127.0.0.1:1", "--state-endpoint", pub.actual_endpoint)
    finally:
        pub.close()
    assert proc.returncode == 1
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("aioadept state: "), proc.stderr


def test_the_state_command_says_at_once_that_nothing_answers_and_keeps_trying(tmp_path):
    """Pointed at a port where nothing listens, ``aioadept state`` says so after READY (never silence), and keeps
    trying."""
    from aioadept.ports import free_port

    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "aioadept", "state", "--robot", f"127.0.0.1:{port}",
                             "--state-endpoint", "tcp://127.0.0.1:0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().startswith("READY ")
        first = proc.stderr.readline()
        assert f"no state stream at 127.0.0.1:{port} (nothing listens there); still trying (1 attempt)" in first
        assert "WARNING" in first and "Traceback" not in first
        assert proc.poll() is None
    finally:
        proc.terminate()
        proc.wait(10)
