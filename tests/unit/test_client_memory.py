"""RobotClient over the in-memory stream pair (no sockets): framing under fragmentation, results, submit, errors."""

from __future__ import annotations

import asyncio

import pytest

from aioadept import Break, MoveTo, MoveToolZ, SetSpeed, Skill
from aioadept.client import ExecResult, RobotClient
from aioadept.errors import AckTimeout, CommandAborted, CommandError, ConnectionLost
from aioadept.protocol import Ack, LineFramer, Status, encode_ack, parse_command
from aioadept.testing import Reply, ScriptedServer, memory_connector, stream_pair


@pytest.mark.timeout(10)
async def test_one_byte_fragmentation_in_both_directions():
    server = ScriptedServer()
    robot = RobotClient(connector=server.connector(chunk_size=1, server_chunk_size=1), id_start=0x10)
    try:
        async with robot:
            res = await robot.cmdexec_joined(SetSpeed(20), MoveToolZ(2.5), MoveTo([1, 2, 3, 4, 5, 6]))
    finally:
        await server.close()
    conn = server.connections[0]
    assert all(len(c) == 1 for c in conn.chunks)                      # really fragmented
    assert conn.ids("recv") == ["00000010", "00000011", "00000012", "00000013", "00000014"]
    assert [m.id for m in res] == conn.ids("recv")
    assert isinstance(res, ExecResult) and len(res) == 5
    assert [m.skill for m in res.commands[1].messages] == ["move_rel_tool", "break"]
    assert res.pose == server.pose


@pytest.mark.timeout(10)
async def test_submit_returns_a_future_per_message():
    server = ScriptedServer({"break": Reply(delay_s=0.01)})
    try:
        async with RobotClient(connector=server.connector()) as robot:
            sub = robot.submit(MoveToolZ(1), SetSpeed(3))
            assert len(sub.futures) == 3 and len(set(sub.ids)) == 3
            assert set(robot.pending_ids) == set(sub.ids)
            first = await sub.futures[0]
            assert first.skill == "move_rel_tool" and first.ok
            results = await sub.wait()
            assert [r.skill for r in results] == ["move_rel_tool", "break", "set_speed"]
            assert robot.pending_ids == () and sub.done()
    finally:
        await server.close()


@pytest.mark.timeout(10)
async def test_error_and_aborted_statuses_become_typed_errors_with_results():
    script = {"move_to": Reply.error(-1003, "joint limit"), "set_speed": Reply.aborted()}
    server = ScriptedServer(script)
    try:
        async with RobotClient(connector=server.connector()) as robot:
            with pytest.raises(CommandError) as err:
                await robot.cmdexec_joined(MoveTo([0, 0, 0, 0, 0, 0]), SetSpeed(5))
            with pytest.raises(CommandAborted) as ab:
                await robot.cmdexec(Break(), SetSpeed(9), Break())
    finally:
        await server.close()
    # joined: all acks are in; the first *error* in message order is raised
    assert [r.status for r in err.value.results] == [Status.ERROR, Status.DONE, Status.ABORTED]
    assert (err.value.code, err.value.message, err.value.skill) == (-1003, "joint limit", "move_to")
    assert ab.value.skill == "set_speed"
    assert [c.command for c in ab.value.completed.commands] == [Break()]   # commands done before the failing one
    assert server.lines()[-1].endswith(b":set_speed:9")             # the last Break was never sent


@pytest.mark.timeout(10)
async def test_joined_raises_the_first_failing_message_in_send_order():
    script = lambda msg, i: Reply.error(-300, f"fail {i}") if msg.skill == "grip" else None  # noqa: E731
    server = ScriptedServer(script)
    try:
        async with RobotClient(connector=server.connector()) as robot:
            with pytest.raises(CommandError) as info:
                await robot.cmdexec_joined(SetSpeed(1), Skill("grip"), Skill("grip"))
    finally:
        await server.close()
    assert info.value.message == "fail 1" and info.value.code == -300 and info.value.skill == "grip"


@pytest.mark.timeout(10)
async def test_connection_lost_in_memory_and_unresolved_ids():
    server = ScriptedServer(drop_after=2)
    try:
        robot = RobotClient(connector=server.connector())
        async with robot:
            with pytest.raises(ConnectionLost) as info:
                await robot.cmdexec_joined(SetSpeed(1), SetSpeed(2), SetSpeed(3))
            ids = server.connections[0].ids("recv")
            assert info.value.acked == (ids[0],) and info.value.unresolved == tuple(ids[1:])
            assert robot.state.value == "lost"
    finally:
        await server.close()


@pytest.mark.timeout(10)
async def test_memory_connector_with_a_custom_handler_and_timeout():
    seen = []

    async def handler(reader, writer):
        framer = LineFramer()
        while data := await reader.read(100):
            for line in framer.feed(data):
                msg = parse_command(line)
                seen.append(msg)
                if msg.skill != "hang":
                    writer.write(encode_ack(Ack(msg.id, Status.DONE, 0.0, 0.0, __import__("aioadept").Pose())))

    connector = memory_connector(handler)
    try:
        async with RobotClient(connector=connector, ack_timeout_s=0.05) as robot:
            assert (await robot.cmdexec(Break())).messages[0].ok
            with pytest.raises(AckTimeout):
                await robot.cmdexec(Skill("hang"))
            assert robot.pending_ids == ()
    finally:
        await connector.aclose()
    assert [m.skill for m in seen] == ["break", "hang"]


@pytest.mark.timeout(10)
async def test_stream_pair_delivers_in_order_and_eof_on_close():
    (cr, cw), (sr, sw) = stream_pair(chunk_size=3)
    cw.write(b"hello ")
    cw.write(b"world")
    cw.close()
    assert await sr.read() == b"hello world"
    await cw.wait_closed()
    assert sw.is_closing()  # the peer closed: this end is torn down too, as with TCP
    sw.write(b"x")          # and writing goes nowhere without raising


@pytest.mark.timeout(10)
async def test_here_and_hello_extension_helpers():
    server = ScriptedServer(server_name="unit-server")
    try:
        async with RobotClient(connector=server.connector()) as robot:
            assert await robot.hello() == (1, "unit-server")
            assert await robot.here() == server.pose
            stop = await robot.stop()
            assert stop.ok and stop.skill == "stop"
    finally:
        await server.close()
    assert [parse_command(x).skill for x in server.lines()] == ["hello", "here", "stop"]


async def test_cmdexec_needs_a_command_and_rejects_non_commands():
    robot = RobotClient()
    with pytest.raises(ValueError, match="commands"):
        await robot.cmdexec()
    with pytest.raises(TypeError, match=r"commands\[0\]"):
        await robot.cmdexec_joined("break")  # type: ignore[arg-type]
    assert asyncio.get_running_loop() is not None


@pytest.mark.timeout(10)
async def test_default_timeouts_share_one_watchdog_and_custom_ones_do_not_wait_for_it():
    server = ScriptedServer(silent_after=1)
    try:
        async with RobotClient(connector=server.connector(), ack_timeout_s=1.0) as robot:
            loop = asyncio.get_running_loop()
            t0 = loop.time()
            slow = [asyncio.create_task(robot.submit(Break()).wait()) for _ in range(3)]
            # a shorter per-call timeout and a lowered default are not held up behind the 1 s deadlines
            with pytest.raises(AckTimeout):
                await robot.submit(Break()).wait(timeout_s=0.05)
            assert loop.time() - t0 < 0.8
            robot.ack_timeout_s = 0.05
            t1 = loop.time()
            with pytest.raises(AckTimeout):
                await robot.cmdexec(Break())
            assert loop.time() - t1 < 0.8
            for task in slow:
                with pytest.raises(AckTimeout):
                    await task
            assert 0.99 <= loop.time() - t0 < 3.0
            assert robot.pending_ids == ()
    finally:
        await server.close()



@pytest.mark.timeout(10)
async def test_cmdexec_of_one_command_returns_a_plain_exec_result():
    """The one-command path builds its ExecResult inline; it must be exactly the dataclass value."""
    import dataclasses

    server = ScriptedServer()
    try:
        async with RobotClient(connector=server.connector()) as robot:
            cmd = Skill("noop")
            res = await robot.cmdexec(cmd)
    finally:
        await server.close()
    assert type(res) is ExecResult
    assert res == ExecResult(res.messages, (cmd,), (1,)) and res.sent == (cmd,) and res.sizes == (1,)
    assert len(res) == 1 and res.commands[0].command is cmd and dataclasses.replace(res).messages == res.messages
