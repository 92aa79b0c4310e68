"""The simulated controller served in-process over real TCP (running_sim), driven by RobotClient and raw sockets."""

from __future__ import annotations

import asyncio
import uuid
from itertools import pairwise

import pytest

from aioadept import Break, MoveJoints, MoveRelJoints, MoveRelTool, MoveTo, SetSpeed, Skill
from aioadept.client import RobotClient
from aioadept.errors import AckTimeout, CommandAborted, CommandError, ConnectionLost
from aioadept.geometry import Pose, poses_close, rel_tool
from aioadept.protocol import NO_ID, ErrorCode, LineFramer, Status, parse_ack
from aioadept.robots import viper_s850 as kin
from aioadept.testing.sim import running_sim

HOME = kin.HOME_JOINTS_DEG
INIT_MOVE = (MoveJoints(list(HOME)), MoveRelJoints([-90, 60, 30, -90, 0, 0]), MoveRelTool([40, -25, 185, 0, 0, 0]),
             MoveRelJoints([0, 0, 0, 0, 0, 1.5]))


def expected_after_init_move() -> Pose:
    approach = kin.forward([-90, -30, 210, -90, 90, 0])
    return rel_tool(approach, (40, -25, 185, 0, 0, 0)) @ Pose(0, 0, 0, 0, 0, 1.5)


async def raw_exchange(host, port, data: bytes, n_acks: int, *, close_after_write=False):
    """Write ``data`` in one write, read ``n_acks`` ack lines; return the parsed acks."""
    reader, writer = await asyncio.open_connection(host, port)
    try:
        writer.write(data)
        await writer.drain()
        framer = LineFramer(max_line=1024)
        acks = []
        while len(acks) < n_acks:
            chunk = await reader.read(4096)
            if not chunk:
                break
            acks += [parse_ack(line) for line in framer.feed(chunk)]
        return acks
    finally:
        writer.close()
        await writer.wait_closed()


@pytest.mark.timeout(20)
async def test_paper_init_move_and_timing_with_robot_client():
    async with running_sim(time_scale=50) as sim, RobotClient(sim.host, sim.port) as robot:
        assert await robot.hello() == (1, f"aioadept-sim {sim.controller.version}")
        res = await robot.cmdexec(*INIT_MOVE)
        assert poses_close(res.pose, expected_after_init_move(), tol_mm=2e-3, tol_deg=2e-3)
        # Each motion: the move acks as it starts, the break when the arm has arrived.
        move, brk = res.commands[1].messages
        assert move.ack.t_done_s <= brk.ack.t_start_s + 1e-3
        expected = kin.forward([-90, -30, 210, -90, 90, 0])
        assert poses_close(brk.ack.pose, expected, tol_mm=2e-3, tol_deg=2e-3)
        assert poses_close(move.ack.pose, kin.forward(HOME), tol_mm=2e-3, tol_deg=2e-3)
        assert await robot.here() == res.pose


@pytest.mark.timeout(20)
async def test_set_speed_applies_to_one_motion_over_tcp():
    async with running_sim(time_scale=20) as sim, RobotClient(sim.host, sim.port) as robot:
        slow = await robot.cmdexec_joined(SetSpeed(50), MoveJoints([100, -90, 180, 0, 90, 0]))
        fast = await robot.cmdexec(MoveJoints(list(HOME)))
        t_slow = slow.messages[-1].ack.t_done_s - slow.messages[1].ack.t_start_s
        t_fast = fast.messages[-1].ack.t_done_s - fast.messages[0].ack.t_start_s
        # 100 deg on J1: 0.5 s at 100 %, 0.9 s at 50 %, divided by the time scale (ack clock is real time).
        assert t_slow == pytest.approx(0.9 / 20, abs=0.006)
        assert t_fast == pytest.approx(0.5 / 20, abs=0.006)


@pytest.mark.timeout(20)
async def test_two_clients_at_once_are_served_serially_with_own_acks():
    async with running_sim(time_scale=10) as sim, \
            RobotClient(sim.host, sim.port) as a, RobotClient(sim.host, sim.port) as b:
        ta = asyncio.create_task(a.cmdexec(MoveJoints([60, -90, 180, 0, 90, 0])))
        await asyncio.sleep(0)  # let a's write go first
        # The first motion takes 0.34 s / 10; b's here waits behind a's break, in arrival order.
        res_a = await ta
        pose_b = await b.here()
        assert poses_close(pose_b, res_a.pose, tol_mm=2e-3, tol_deg=2e-3)
        both = await asyncio.gather(a.cmdexec(MoveJoints([30, -90, 180, 0, 90, 0])),
                                    b.cmdexec(MoveJoints([-30, -90, 180, 0, 90, 0])))
        # Both finished; the later arrival determines where the arm ends.
        finals = {round(r.pose.y) for r in both}
        assert len(finals) == 2
        assert a.stats.unknown_acks == b.stats.unknown_acks == 0
        assert sim.controller.connections == frozenset({1, 2})


@pytest.mark.timeout(20)
@pytest.mark.parametrize("command,code", [
    (Skill("fly"), ErrorCode.UNKNOWN_SKILL),
    (Skill("move_to", 1.0, 2.0), ErrorCode.WRONG_ARGUMENT_COUNT),
    (Skill("set_speed", 0), ErrorCode.ILLEGAL_VALUE),  # SetSpeed(0) is refused client-side
    (Skill("set_speed", 150), ErrorCode.ILLEGAL_VALUE),
    (MoveTo([2000, 0, 500, 0, 180, 0]), ErrorCode.OUT_OF_REACH),
    (MoveJoints([0, -90, 180, 0, 125, 0]), ErrorCode.JOINT_LIMIT),
    (MoveRelJoints([0, 0, 90, 0, 0, 0]), ErrorCode.JOINT_LIMIT),
])
async def test_error_acks_over_tcp_and_the_server_keeps_serving(command, code):
    async with running_sim(instant=True) as sim, RobotClient(sim.host, sim.port) as robot:
        with pytest.raises(CommandError) as info:
            await robot.cmdexec(command)
        assert info.value.code == code
        assert sim.controller.joints_at(sim.now()) == pytest.approx(HOME)
        res = await robot.cmdexec(MoveRelJoints([5, 0, 0, 0, 0, 0]))
        assert res.messages[-1].ok


@pytest.mark.timeout(20)
async def test_malformed_and_oversize_lines_get_error_acks():
    async with running_sim(instant=True) as sim:
        data = (b"abcd0001:move_to:1,2,oops,4,5,6\r\n"
                b"no id here\r\n"
                b"abcd0002:move_to:" + b"1.000," * 30 + b"1\r\n"
                b"abcd0003:here\r\n")
        acks = await raw_exchange(sim.host, sim.port, data, 4)
        assert [(a.id, a.status, a.error_code) for a in acks] == [
            ("abcd0001", Status.ERROR, ErrorCode.ILLEGAL_VALUE),
            (NO_ID, Status.ERROR, ErrorCode.MALFORMED_MESSAGE),
            ("abcd0002", Status.ERROR, ErrorCode.LINE_TOO_LONG),
            ("abcd0003", Status.DONE, None),
        ]


@pytest.mark.timeout(20)
async def test_original_client_style_traffic():
    """What pyadept does: uuid4()[:8] IDs, '%.3f' args, many lines in one write, CRLF, elements[:4] of each ack."""
    async with running_sim(instant=True) as sim:
        ids = [uuid.uuid4().hex[:8].encode() for _ in range(4)]
        lines = [b"move_joints:0.000,-90.000,180.000,0.000,90.000,0.000", b"break",
                 b"move_to:-80.000,-481.000,112.500,180.000,90.000,180.000", b"break"]
        data = b"".join(i + b":" + line + b"\r\n" for i, line in zip(ids, lines, strict=True))
        reader, writer = await asyncio.open_connection(sim.host, sim.port)
        writer.write(data)
        pending = set(ids)
        buf = b""
        while pending:
            buf += await reader.read(1024)
            *messages, buf = buf.split(b"\r\n")
            for msg in messages:
                msg_id, status, timestamp, pose = msg.split(b":")[:4]
                pending.remove(msg_id)
                assert status == b"done" and len(msg.split(b":")) == 4  # no trailing fields for its skills
                t0, t1 = map(float, timestamp.split(b","))
                assert 0 <= t0 <= t1 and len(pose.split(b",")) == 6
        assert poses_close(Pose(*map(float, pose.split(b","))), Pose(-80, -481, 112.5, 180, 90, 180), tol_mm=2e-3,
                           tol_deg=2e-3)
        writer.close()
        await writer.wait_closed()


@pytest.mark.timeout(20)
async def test_stop_during_break_aborts_and_the_robot_rests_short_of_the_target():
    async with running_sim() as sim, RobotClient(sim.host, sim.port) as robot:
        sub = robot.submit(SetSpeed(20), MoveJoints([150, -90, 180, 0, 90, 0], break_move=False), Break(),
                           Skill("here"))
        # Wait until the server is inside the break (the move has been acked), then stop.
        await sub.futures[1]
        stop = await robot.stop()
        assert stop.ack.status is Status.DONE
        with pytest.raises(CommandAborted):
            await sub.wait()
        statuses = [f.result().ack.status for f in sub.futures]
        assert statuses == [Status.DONE, Status.DONE, Status.ABORTED, Status.ABORTED]
        j1 = sim.controller.joints_at(sim.now())[0]
        assert 0 <= j1 < 150 and not sim.controller.trajectory.in_motion(sim.now())
        assert poses_close(await robot.here(), stop.ack.pose, tol_mm=2e-3, tol_deg=2e-3)


@pytest.mark.timeout(20)
async def test_disconnect_discards_the_clients_queued_commands():
    async with running_sim(time_scale=5) as sim:
        reader, writer = await asyncio.open_connection(sim.host, sim.port)
        writer.write(b"aaaa0001:move_joints:40,-90,180,0,90,0\r\naaaa0002:break\r\n"
                     b"aaaa0003:move_joints:-40,-90,180,0,90,0\r\naaaa0004:enable_air\r\n")
        line = await reader.readuntil(b"\r\n")  # the first move's ack: the break is now waiting
        assert line.startswith(b"aaaa0001:done")
        assert sim.controller.queued() == 2
        writer.close()
        await writer.wait_closed()
        async with RobotClient(sim.host, sim.port) as robot:
            pose = (await robot.cmdexec(Break())).pose  # waits for the motion a's move started
        assert sim.controller.queued() == 0
        assert poses_close(pose, kin.forward([40, -90, 180, 0, 90, 0]), tol_mm=2e-3, tol_deg=2e-3)
        assert sim.controller.air is False


@pytest.mark.timeout(20)
async def test_max_clients_and_allow_list_refuse_with_server_busy():
    async with running_sim(instant=True, max_clients=1) as sim, RobotClient(sim.host, sim.port) as robot:
        await robot.here()
        acks = await raw_exchange(sim.host, sim.port, b"", 1)
        assert acks[0].id == NO_ID and acks[0].error_code == ErrorCode.SERVER_BUSY
        assert "too many" in acks[0].error_message
    async with running_sim(instant=True, allow=("10.1.2.3",)) as sim:
        acks = await raw_exchange(sim.host, sim.port, b"abcd0001:here\r\n", 1)
        assert acks[0].error_code == ErrorCode.SERVER_BUSY and "not allowed" in acks[0].error_message
        assert sim.rejected_total == 1
    async with running_sim(instant=True, allow=("127.0.0.1",)) as sim:
        acks = await raw_exchange(sim.host, sim.port, b"abcd0001:here\r\n", 1)
        assert acks[0].status is Status.DONE


@pytest.mark.timeout(20)
async def test_fault_ack_delay():
    async with running_sim(instant=True, ack_delay_s=0.2) as sim, RobotClient(sim.host, sim.port) as robot:
        res = await robot.cmdexec(MoveRelJoints([1, 0, 0, 0, 0, 0]))
        assert all(m.rtt_s >= 0.19 for m in res.messages)
        assert [m.skill for m in res.messages] == ["move_rel_joints", "break"]


@pytest.mark.timeout(20)
async def test_fault_drop_after_n_messages():
    async with running_sim(time_scale=2, drop_after=3) as sim, RobotClient(sim.host, sim.port) as robot:
        await robot.here()  # message 1
        with pytest.raises(ConnectionLost) as info:
            # messages 2 and 3: the move is acked at once, the break's ack never comes.
            await robot.cmdexec(MoveJoints([50, -90, 180, 0, 90, 0]))
        assert len(info.value.acked) == 1 and len(info.value.unresolved) == 1


@pytest.mark.timeout(20)
async def test_fault_silent_server_executes_but_never_acks():
    async with running_sim(instant=True, silent=True) as sim, \
            RobotClient(sim.host, sim.port, ack_timeout_s=0.3) as robot:
        with pytest.raises(AckTimeout):
            await robot.cmdexec(MoveJoints([20, -90, 180, 0, 90, 0]))
        assert sim.controller.joints_at(sim.now())[0] == pytest.approx(20)


@pytest.mark.timeout(20)
async def test_state_stream_publishes_robot_state():
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.pubsub import Subscriber

    async with running_sim(time_scale=10, state_endpoint="tcp://127.0.0.1:0", state_rate_hz=200) as sim:
        assert sim.state_endpoint.startswith("tcp://127.0.0.1:")
        async with Subscriber(sim.state_endpoint, topics=[ROBOT_STATE_TOPIC]) as sub, \
                RobotClient(sim.host, sim.port) as robot:
            topic, payload = await sub.recv()  # waits for the subscription to take effect (no sleep)
            first = RobotState.from_bytes(payload)
            assert topic == ROBOT_STATE_TOPIC and first.joints_deg == pytest.approx(HOME)
            await robot.cmdexec(Skill("enable_air"), SetSpeed(50))
            sub_moving = robot.submit(MoveJoints([90, -90, 180, 0, 90, 0]), Break())
            seen_motion = False
            while not sub_moving.done():
                st = RobotState.from_bytes((await sub.recv())[1])
                seen_motion |= st.in_motion and 0 < st.joints_deg[0] < 90 and st.speed_pct == 50
            await sub_moving.wait()
            st = RobotState.from_bytes((await sub.recv())[1])
            while st.in_motion:
                st = RobotState.from_bytes((await sub.recv())[1])
            assert seen_motion and st.air and st.joints_deg[0] == pytest.approx(90, abs=1e-6)
            assert poses_close(st.pose, kin.forward(st.joints_deg), tol_mm=1e-6)
            assert abs(st.wall_time_s - (sim.wall_time_at_start_s + st.t_s)) < 1e-6


@pytest.mark.timeout(20)
async def test_lines_split_anywhere_and_bare_lf_are_served():
    async with running_sim(instant=True) as sim:
        reader, writer = await asyncio.open_connection(sim.host, sim.port)
        data = b"abcd0001:move_rel_joints:1.000,0,0,0,0,0\r\nabcd0002:break\nabcd0003:here\r\n"
        for i in range(len(data)):  # one byte per write: the server must not care how TCP cuts the stream
            writer.write(data[i:i + 1])
            await writer.drain()
        lines = [await reader.readuntil(b"\r\n") for _ in range(3)]
        assert [line[:14] for line in lines] == [b"abcd0001:done:", b"abcd0002:done:", b"abcd0003:done:"]
        assert sim.controller.joints_at(sim.now())[0] == pytest.approx(1.0)
        writer.close()
        await writer.wait_closed()


@pytest.mark.timeout(20)
async def test_closing_the_server_with_a_client_waiting_ends_cleanly(caplog):
    sim_cm = running_sim()
    sim = await sim_cm.__aenter__()
    reader, writer = await asyncio.open_connection(sim.host, sim.port)
    writer.write(b"abcd0001:move_joints:100,-90,180,0,90,0\r\nabcd0002:break\r\n")
    assert (await reader.readuntil(b"\r\n")).startswith(b"abcd0001:done:")
    assert sim.controller.busy  # the break waits for the motion
    await sim_cm.__aexit__(None, None, None)
    assert await reader.read() == b""  # the connection was closed; the break never acked
    writer.close()
    assert not [r for r in caplog.records if r.levelname in ("ERROR", "CRITICAL")]


@pytest.mark.timeout(20)
async def test_state_stream_rate():
    import statistics

    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.pubsub import Subscriber

    async with running_sim(instant=True, state_endpoint="tcp://127.0.0.1:0", state_rate_hz=50) as sim, \
            Subscriber(sim.state_endpoint, topics=[ROBOT_STATE_TOPIC]) as sub:
        ts = [RobotState.from_bytes((await sub.recv())[1]).t_s for _ in range(16)]
        gaps = [b - a for a, b in pairwise(ts)]
        assert all(g > 0 for g in gaps)
        assert statistics.median(gaps) == pytest.approx(0.02, rel=0.3)
