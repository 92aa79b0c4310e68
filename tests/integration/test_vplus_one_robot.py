"""``aioadept sim --vplus``: the same robot as the Python backend, in a real child process over real TCP and
ZeroMQ: the state stream shows the arm the V+ program moves, --time-scale shortens its motions, --fault
injects the same misbehaviour (silent, ack-delay, drop-after)."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from aioadept import MoveToolZ, SetSpeed
from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import Subscriber
from aioadept.client import RobotClient
from aioadept.robots import viper_s850 as kin
from aioadept.testing.nodes import running_node

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
FILES = [str(VPLUS / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]


def vplus_args(*extra: str) -> tuple[str, ...]:
    return ("--vplus", *FILES, "--run", "rs.main", "--map-port", "1234=0", "--map-port", "1235=0", *extra)


async def next_state(sub: Subscriber) -> RobotState:
    return RobotState.from_bytes((await asyncio.wait_for(sub.recv(), 5.0))[1])


@pytest.mark.timeout(60)
async def test_state_stream_shows_the_arm_the_v_plus_program_moves(tmp_path):
    async with running_node("sim", *vplus_args("--state-endpoint", "tcp://127.0.0.1:0", "--state-rate-hz", "100",
                                               "--time-scale", "2"), log_path=tmp_path / "sim.log") as node:
        assert node.ready["state"].startswith("tcp://127.0.0.1:")
        async with Subscriber(node.ready["state"], topics=[ROBOT_STATE_TOPIC]) as sub:
            st = await next_state(sub)
            assert st.joints_deg == pytest.approx(kin.HOME_JOINTS_DEG) and not st.in_motion
            z0 = st.pose.z
            async with RobotClient("127.0.0.1", int(node.ready["port"])) as robot:
                await robot.cmdexec(SetSpeed(20), MoveToolZ(60.0))      # move_rel_tool, break: at rest now
                end = await robot.here()
            assert end.z == pytest.approx(z0 - 60.0, abs=0.01)
            # the samples queued while the V+ program moved the arm: it went down through the stream
            moving = []
            while True:
                st = await next_state(sub)
                if st.in_motion:
                    moving.append(st.pose.z)
                elif st.pose.z == pytest.approx(end.z, abs=0.01):
                    break
            assert any(z0 - 1.0 > z > z0 - 59.0 for z in moving)
            assert moving == sorted(moving, reverse=True)


async def motion_time(tmp_path: Path, scale: str) -> float:
    async with running_node("sim", *vplus_args("--state-endpoint", "none", "--time-scale", scale),
                            log_path=tmp_path / f"sim-{scale}.log") as node:
        async with RobotClient("127.0.0.1", int(node.ready["port"])) as robot:
            res = await robot.cmdexec(SetSpeed(50), MoveToolZ(100.0))      # move_rel_tool, break
            move, brk = res.messages[-2].ack, res.messages[-1].ack
            return brk.t_done_s - move.t_start_s


@pytest.mark.timeout(90)
async def test_time_scale_shortens_the_motion(tmp_path):
    slow = await motion_time(tmp_path, "1")
    fast = await motion_time(tmp_path, "10")
    # server-clock times from the acks; the model's motion at scale 10 takes a tenth (plus a poll or two)
    assert slow > 0.2
    assert fast < slow / 4


@pytest.mark.timeout(60)
async def test_fault_ack_delay_and_silent_and_drop_after(tmp_path):
    async with running_node("sim", *vplus_args("--state-endpoint", "none", "--fault", "ack-delay=0.3"),
                            log_path=tmp_path / "delay.log") as node:
        reader, writer = await asyncio.open_connection("127.0.0.1", int(node.ready["port"]))
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        writer.write(b"a0000001:here\r\na0000002:here\r\n")
        first = await asyncio.wait_for(reader.readuntil(b"\n"), 10)
        second = await asyncio.wait_for(reader.readuntil(b"\n"), 10)
        assert loop.time() - t0 >= 0.29
        assert first.startswith(b"a0000001:done:") and second.startswith(b"a0000002:done:")   # order kept
        writer.close()
    async with running_node("sim", *vplus_args("--state-endpoint", "none", "--fault", "silent"),
                            log_path=tmp_path / "silent.log") as node:
        reader, writer = await asyncio.open_connection("127.0.0.1", int(node.ready["port"]))
        writer.write(b"s0000001:here\r\n")
        with pytest.raises(TimeoutError):
            await asyncio.wait_for(reader.readuntil(b"\n"), 0.5)
        writer.close()
    async with running_node("sim", *vplus_args("--state-endpoint", "none", "--fault", "drop-after=2"),
                            log_path=tmp_path / "drop.log") as node:
        reader, writer = await asyncio.open_connection("127.0.0.1", int(node.ready["port"]))
        writer.write(b"d0000001:here\r\nd0000002:here\r\nd0000003:here\r\n")
        rest = await asyncio.wait_for(reader.read(), 10)      # until the server closes
        lines = rest.split(b"\r\n")
        assert [ln[:14] for ln in lines if ln] == [b"d0000001:done:", b"d0000002:done:"]
        writer.close()
        # the server goes on serving new connections
        async with RobotClient("127.0.0.1", int(node.ready["port"])) as robot:
            assert (await robot.hello())[1] == "aioadept-vplus 0.1.0"
