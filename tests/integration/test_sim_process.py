"""``aioadept sim`` as a real subprocess: READY line, RobotClient over TCP, state stream, clean exit on signals."""

from __future__ import annotations

import asyncio
import contextlib
import signal

import pytest

from aioadept import MoveJoints, MoveRelJoints, MoveRelTool, MoveTo, SetSpeed, Skill
from aioadept.client import RobotClient
from aioadept.errors import CommandError
from aioadept.geometry import Pose, poses_close, rel_tool
from aioadept.protocol import ErrorCode
from aioadept.robots import viper_s850 as kin
from aioadept.testing.nodes import running_node



@contextlib.asynccontextmanager
async def sim_process(*args: str):
    """Start ``aioadept sim --port 0 ...``; yield (process, READY fields); stopped on exit."""
    async with running_node("sim", "--port", "0", *args, expect_clean_exit=False) as node:
        yield node.proc, node.ready


@pytest.mark.timeout(30)
async def test_sim_subprocess_runs_the_paper_init_move_and_exits_cleanly_on_sigterm():
    async with sim_process("--time-scale", "50", "--state-endpoint", "none") as (proc, ready):
        assert ready["host"] == "127.0.0.1" and int(ready["port"]) > 0 and ready["state"] == "none"
        async with RobotClient(ready["host"], int(ready["port"])) as robot:
            version, name = await robot.hello()
            assert version == 1 and name.startswith("aioadept-sim ")
            res = await robot.cmdexec(MoveJoints([0, -90, 180, 0, 90, 0]), MoveRelJoints([-90, 60, 30, -90, 0, 0]),
                                      MoveRelTool([40, -25, 185, 0, 0, 0]), MoveRelJoints([0, 0, 0, 0, 0, 1.5]))
        expected = rel_tool(kin.forward([-90, -30, 210, -90, 90, 0]), (40, -25, 185, 0, 0, 0)) @ Pose(0, 0, 0, 0, 0, 1.5)
        assert poses_close(res.pose, expected, tol_mm=2e-3, tol_deg=2e-3)
        # Ack clock: seconds since the server started, increasing.
        times = [t for m in res.messages for t in (m.ack.t_start_s, m.ack.t_done_s)]
        assert times == sorted(times) and 0 <= times[0] < 30
        proc.send_signal(signal.SIGTERM)
        async with asyncio.timeout(5):
            assert await proc.wait() == 0


@pytest.mark.timeout(30)
async def test_sim_subprocess_two_clients_and_errors_then_sigint():
    async with sim_process("--instant", "--state-endpoint", "none", "--monitor-speed", "50") as (proc, ready):
        host, port = ready["host"], int(ready["port"])
        async with RobotClient(host, port) as a, RobotClient(host, port) as b:
            ra, rb = await asyncio.gather(a.cmdexec(SetSpeed(30), MoveJoints([10, -90, 180, 0, 90, 0])),
                                          b.cmdexec(MoveJoints([-10, -90, 180, 0, 90, 0])))
            assert ra.messages[-1].ok and rb.messages[-1].ok
            for cmd, code in [(Skill("fly"), ErrorCode.UNKNOWN_SKILL),
                              (Skill("move_to", 1.0), ErrorCode.WRONG_ARGUMENT_COUNT),
                              (Skill("set_speed", 101), ErrorCode.ILLEGAL_VALUE),
                              (MoveTo([0, 0, 2000, 0, 180, 0]), ErrorCode.OUT_OF_REACH),
                              (MoveRelJoints([0, 0, 0, 0, -300, 0]), ErrorCode.JOINT_LIMIT)]:
                with pytest.raises(CommandError) as info:
                    await a.cmdexec(cmd)
                assert info.value.code == code
            before = await b.here()
            assert (await a.here()) == before  # nothing moved on errors
        # An oversize line over a raw socket.
        reader, writer = await asyncio.open_connection(host, port)
        # Oversize, a bad number, no ID at all, then a good line: errors in order, and the server goes on.
        writer.write(b"abcd0001:move_to:" + b"9" * 200 + b"\r\nabcd0003:move_to:1,2,x,4,5,6\r\ngarbage line\r\n"
                     b"abcd0002:here\r\n")
        lines = [await reader.readuntil(b"\r\n") for _ in range(4)]
        assert lines[0].startswith(b"abcd0001:error:") and b":-402:" in lines[0]
        assert lines[1].startswith(b"abcd0003:error:") and b":-410:" in lines[1]
        assert lines[2].startswith(b"00000000:error:") and b":-401:" in lines[2]
        assert lines[3].startswith(b"abcd0002:done:")
        writer.close()
        await writer.wait_closed()
        proc.send_signal(signal.SIGINT)
        async with asyncio.timeout(5):
            assert await proc.wait() == 0


@pytest.mark.timeout(30)
async def test_sim_subprocess_publishes_state_and_injects_faults():
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.pubsub import Subscriber

    async with sim_process("--instant", "--state-endpoint", "tcp://127.0.0.1:0", "--state-rate-hz", "50",
                           "--fault", "ack-delay=0.15", "--max-clients", "1") as (proc, ready):
        assert ready["state"].startswith("tcp://127.0.0.1:")
        async with Subscriber(ready["state"], topics=[ROBOT_STATE_TOPIC]) as sub:
            st = RobotState.from_bytes((await sub.recv())[1])
            assert st.joints_deg == pytest.approx(kin.HOME_JOINTS_DEG) and not st.in_motion
            async with RobotClient(ready["host"], int(ready["port"])) as robot:
                res = await robot.cmdexec(MoveJoints([20, -90, 180, 0, 90, 0]))
                assert min(m.rtt_s for m in res.messages) >= 0.14
                # A second client is one too many: refused with a SERVER_BUSY error ack, then closed.
                reader, writer = await asyncio.open_connection(ready["host"], int(ready["port"]))
                refusal = await reader.read()
                assert refusal.startswith(b"00000000:error:") and b":-530:" in refusal
                writer.close()
            while not st.joints_deg[0] == pytest.approx(20, abs=1e-6):
                st = RobotState.from_bytes((await sub.recv())[1])


def test_bad_options_exit_with_usage_error():
    from aioadept.cli.sim import main

    with pytest.raises(SystemExit) as info:
        main(["--fault", "explode"])
    assert info.value.code == 2
    with pytest.raises(SystemExit):
        main(["--time-scale", "0"])
