"""RobotClient over real TCP on 127.0.0.1 against the ScriptedServer (and a few raw asyncio servers)."""

from __future__ import annotations

import asyncio
import re

import pytest

from aioadept import Break, MoveTo, MoveToolZ, SetSpeed, Skill
from aioadept.client import MessageResult, RobotClient, SentMessage
from aioadept.errors import (
    AckTimeout,
    ClientStateError,
    CommandAborted,
    CommandError,
    ConnectError,
    ConnectionLost,
)
from aioadept.geometry import Pose
from aioadept.protocol import Ack, AckReader, LineFramer, Status, encode_ack, parse_command
from aioadept.testing import Reply, ScriptedServer

from rawtcp import raw_server

POSE = Pose(480.014, -0.038, 709.975, 0.0, 179.995, 0.004)


class Recorder:
    """An observer that also lets a test wait for the ack of a given skill (no sleeping)."""

    def __init__(self) -> None:
        self.sent: list[SentMessage] = []
        self.acks: list[MessageResult] = []
        self._waiters: dict[str, asyncio.Event] = {}

    def on_send(self, msg: SentMessage) -> None:
        self.sent.append(msg)

    def on_ack(self, result: MessageResult) -> None:
        self.acks.append(result)
        self._event(result.skill).set()

    def _event(self, skill: str) -> asyncio.Event:
        return self._waiters.setdefault(skill, asyncio.Event())

    def forget(self, skill: str) -> None:
        self._waiters.pop(skill, None)

    async def acked(self, skill: str) -> None:
        await self._event(skill).wait()


async def read_lines(reader, framer, n):
    """Read until ``n`` command lines arrived; return them parsed."""
    out = []
    while len(out) < n:
        data = await reader.read(65536)
        if not data:
            break
        out += [parse_command(line) for line in framer.feed(data)]
    return out


def ack_bytes(mid: str, status: Status = Status.DONE, extra=()) -> bytes:
    return encode_ack(Ack(mid, status, 1.0, 1.5, POSE, extra))


# ------------------------------------------------------------------------------------------------ ordering
@pytest.mark.timeout(10)
async def test_joined_writes_everything_before_the_first_ack():
    # The first message takes 50 ms: if all three were written at once the server has read all of them first.
    async with ScriptedServer({"set_speed": Reply(delay_s=0.05)}) as server:
        async with RobotClient(server.host, server.port) as robot:
            res = await robot.cmdexec_joined(SetSpeed(20), MoveToolZ(2.5))
    conn = server.connections[0]
    assert [e.kind for e in conn.events] == ["recv"] * 3 + ["ack"] * 3
    assert [m.skill for m in res] == ["set_speed", "move_rel_tool", "break"]
    assert conn.ids("recv") == conn.ids("ack") == [m.id for m in res]
    assert len({m.batch for m in res}) == 1
    assert len({m.t_send_s for m in res}) == 1  # one write
    assert conn.lines()[1].endswith(b":move_rel_tool:0.000,0.000,2.500,0.000,0.000,0.000")
    assert [c.command for c in res.commands] == [SetSpeed(20), MoveToolZ(2.5)]


@pytest.mark.timeout(10)
async def test_cmdexec_waits_for_each_commands_acks_before_writing_the_next():
    async with ScriptedServer({"set_speed": Reply(delay_s=0.05)}) as server:
        async with RobotClient(server.host, server.port) as robot:
            res = await robot.cmdexec(SetSpeed(20), MoveToolZ(2.5))
    conn = server.connections[0]
    # set_speed is acked (after its 50 ms) before move_rel_tool + break are even received
    assert [(e.kind, e.id) for e in conn.events][:3] == [
        ("recv", res.messages[0].id), ("ack", res.messages[0].id), ("recv", res.messages[1].id)]
    assert conn.chunks[0] == conn.lines()[0] + b"\r\n"
    assert conn.chunks[1] == b"".join(line + b"\r\n" for line in conn.lines()[1:])  # MoveToolZ: one write
    assert [len(c.messages) for c in res.commands] == [1, 2]
    assert res.messages[0].batch != res.messages[1].batch == res.messages[2].batch
    assert res.messages[1].t_send_s >= res.messages[0].t_recv_s
    assert res.pose == server.pose


# ------------------------------------------------------------------------------------------------ errors
@pytest.mark.timeout(10)
async def test_error_ack_raises_command_error_and_later_commands_are_not_sent():
    script = {"move_to": Reply.error(-610, "location out of range")}
    async with ScriptedServer(script) as server:
        async with RobotClient(server.host, server.port) as robot:
            with pytest.raises(CommandError) as info:
                await robot.cmdexec(MoveTo([2000, 0, 0, 0, 180, 0]), SetSpeed(5))
            assert robot.pending_ids == ()
            # the connection stays usable
            ok = await robot.cmdexec(Break())
    exc = info.value
    assert (exc.code, exc.message, exc.skill) == (-610, "location out of range", "move_to")
    assert exc.ack.status is Status.ERROR
    assert [r.skill for r in exc.results] == ["move_to", "break"]  # all acks of the command were awaited
    skills = [parse_command(line).skill for line in server.lines()]
    assert skills == ["move_to", "break", "break"]  # set_speed never went out
    assert ok.messages[0].ok


@pytest.mark.timeout(10)
async def test_server_dies_mid_command_connection_lost_with_acked_and_unresolved_and_nothing_resent():
    async with ScriptedServer(drop_after=4) as server:  # acks 3 messages, drops the connection at the 4th
        async with RobotClient(server.host, server.port) as robot:
            await robot.cmdexec(SetSpeed(50))
            with pytest.raises(ConnectionLost) as info:
                await robot.cmdexec(SetSpeed(20), MoveToolZ(2.5))
            assert robot.pending_ids == ()
            assert robot.state.value == "lost"
            with pytest.raises(ConnectionLost):  # nothing is written on a lost connection
                await robot.cmdexec(Break())
            await robot.connect()  # explicit reconnect
            res = await robot.cmdexec(Break())
    lost = info.value
    first = server.connections[0]
    ids = first.ids("recv")
    assert len(ids) == 4
    assert lost.acked == (ids[1], ids[2])  # this call's set_speed and move_rel_tool were acked
    assert lost.unresolved == (ids[3],)    # the break was dropped at: unknown
    assert first.ids("ack") == ids[:3]
    # nothing re-sent: the second connection saw exactly the new break, with a fresh ID
    second = server.connections[1]
    assert second.ids("recv") == [res.messages[0].id]
    assert len(set(server_id for c in server.connections for server_id in c.ids("recv"))) == 5


@pytest.mark.timeout(10)
async def test_auto_reconnect_reconnects_before_the_next_command_without_resending():
    async with ScriptedServer(drop_after=2) as server:
        async with RobotClient(server.host, server.port, auto_reconnect=True) as robot:
            await robot.cmdexec(SetSpeed(50))
            with pytest.raises(ConnectionLost) as info:
                await robot.cmdexec(SetSpeed(20))
            server.drop_after = None
            await robot.cmdexec(SetSpeed(30))
    assert info.value.unresolved == (server.connections[0].ids("recv")[1],)
    assert [len(c.lines()) for c in server.connections] == [2, 1]
    assert server.connections[1].lines()[0].endswith(b":set_speed:30")


@pytest.mark.timeout(10)
async def test_ack_timeout_then_late_ack_is_dropped_and_counted():
    async with ScriptedServer({"break": Reply(delay_s=1.0)}) as server:
        async with RobotClient(server.host, server.port, ack_timeout_s=5.0) as robot:
            loop = asyncio.get_running_loop()
            t0 = loop.time()
            with pytest.raises(AckTimeout) as info:
                await robot.cmdexec(Break(), timeout_s=0.05)
            assert loop.time() - t0 < 0.8  # the 0.05 s timeout, not the late ack 1 s later (slack for a busy CI)
            assert isinstance(info.value, TimeoutError)
            assert info.value.pending == (server.connections[0].ids("recv")[0],)
            assert robot.pending_ids == ()
            res = await robot.cmdexec(SetSpeed(10))  # served after the late break ack
            assert res.messages[0].ok
            assert (robot.stats.late_acks, robot.stats.unknown_acks) == (1, 0)


@pytest.mark.timeout(10)
async def test_silent_server_times_out_with_configured_default():
    async with ScriptedServer(silent_after=1) as server:
        async with RobotClient(server.host, server.port, ack_timeout_s=0.1) as robot:
            with pytest.raises(AckTimeout) as info:
                await robot.cmdexec_joined(SetSpeed(10), Break())
    assert len(info.value.pending) == 2


# ------------------------------------------------------------------------------------------------ stop
@pytest.mark.timeout(10)
async def test_stop_aborts_the_running_and_queued_commands_and_resolves_their_futures():
    rec = Recorder()
    async with ScriptedServer({"break": Reply(delay_s=5.0)}) as server:
        async with RobotClient(server.host, server.port, observers=[rec]) as robot:
            loop = asyncio.get_running_loop()
            t0 = loop.time()
            task = asyncio.create_task(robot.cmdexec_joined(MoveToolZ(10), SetSpeed(3), MoveToolZ(-10)))
            await rec.acked("move_rel_tool")  # the first break is now "waiting for the motion"
            stop = await robot.stop()
            with pytest.raises(CommandAborted) as info:
                await task
            assert loop.time() - t0 < 2.0
            assert robot.pending_ids == ()
    assert stop.ok and stop.skill == "stop"
    results = info.value.results
    assert [r.status.value for r in results] == ["done", "aborted", "aborted", "aborted", "aborted"]
    assert info.value.skill == "break"
    conn = server.connections[0]
    acks = [(e.id, e.status) for e in conn.events if e.kind == "ack"]
    assert acks == [(r.id, r.status.value) for r in results] + [(stop.id, "done")]  # aborted before stop's done


@pytest.mark.timeout(10)
async def test_stop_against_server_without_the_extension_raises_command_error():
    async def old_server(reader, writer):
        framer = LineFramer()
        while msgs := await read_lines(reader, framer, 1):
            for msg in msgs:
                if msg.skill == "stop":
                    writer.write(encode_ack(Ack.error(msg.id, -406, None, 1.0, 1.0, POSE)))
                else:
                    writer.write(ack_bytes(msg.id))

    async with raw_server(old_server) as port:
        async with RobotClient("127.0.0.1", port) as robot:
            with pytest.raises(CommandError) as info:
                await robot.stop()
    assert info.value.code == -406 and info.value.message == "undefined skill"


# ------------------------------------------------------------------------------------------------ cancellation
@pytest.mark.timeout(10)
async def test_cancelling_a_cmdexec_leaves_no_pending_futures():
    rec = Recorder()
    async with ScriptedServer({"break": Reply(delay_s=0.2)}) as server:
        async with RobotClient(server.host, server.port, observers=[rec]) as robot:
            task = asyncio.create_task(robot.cmdexec(MoveToolZ(1), SetSpeed(5)))
            await rec.acked("move_rel_tool")
            assert len(robot.pending_ids) == 1  # the break
            task.cancel()
            with pytest.raises(asyncio.CancelledError):
                await task
            assert robot.pending_ids == ()
            res = await robot.cmdexec(Break())  # the late break ack arrives first and is dropped quietly
            assert res.messages[0].ok
            assert robot.stats.late_acks == 1 and robot.stats.unknown_acks == 0
    skills = [parse_command(line).skill for line in server.lines()]
    assert skills == ["move_rel_tool", "break", "break"]  # the cancelled cmdexec did not send SetSpeed


# ------------------------------------------------------------------------------------------------ framing over TCP
@pytest.mark.timeout(10)
async def test_acks_written_one_byte_at_a_time_are_reassembled():
    async def dribbler(reader, writer):
        framer = LineFramer()
        msgs = await read_lines(reader, framer, 3)
        for msg in msgs:
            for b in ack_bytes(msg.id):
                writer.write(bytes([b]))
                await writer.drain()

    async with raw_server(dribbler) as port:
        async with RobotClient("127.0.0.1", port) as robot:
            res = await robot.cmdexec_joined(SetSpeed(1), MoveToolZ(1))
    assert [m.ack.pose for m in res] == [POSE] * 3
    assert [m.ack.id for m in res] == [m.id for m in res]
    assert robot.stats.bad_lines == 0


@pytest.mark.timeout(20)
async def test_1000_messages_in_one_write_and_1000_acks_in_one_write():
    seen = {}

    async def coalescing(reader, writer):
        framer = LineFramer()
        chunks = 0
        msgs = []
        while len(msgs) < 1000:
            data = await reader.read(1 << 20)
            chunks += 1
            msgs += [parse_command(line) for line in framer.feed(data)]
        seen["msgs"], seen["chunks"] = msgs, chunks
        writer.write(b"".join(ack_bytes(m.id) for m in msgs))  # one write
        await writer.drain()

    async with raw_server(coalescing) as port:
        async with RobotClient("127.0.0.1", port, max_pending=None) as robot:  # this server has no queue limit
            res = await robot.cmdexec_joined(*[Skill("noop", i) for i in range(1000)])
    assert len(res) == 1000
    assert [m.args for m in res] == [(i,) for i in range(1000)]
    assert [m.id for m in res] == [m.id for m in seen["msgs"]]
    assert [m.args for m in seen["msgs"]] == [(i,) for i in range(1000)]
    assert len(set(m.id for m in res)) == 1000
    assert robot.stats.acks == 1000


@pytest.mark.timeout(10)
async def test_unknown_noid_and_garbage_lines_are_recorded_not_fatal(caplog):
    async def noisy(reader, writer):
        framer = LineFramer()
        for msg in await read_lines(reader, framer, 1):
            writer.write(ack_bytes("deadbeef"))                                   # unknown ID
            writer.write(encode_ack(Ack.error(None, -401, None, 1.0, 1.0, POSE)))  # 00000000
            writer.write(b"this is not an ack\r\n" + b"x" * 1100 + b"\r\n")         # garbage, oversize
            writer.write(ack_bytes(msg.id))
        await reader.read()

    async with raw_server(noisy) as port:
        async with RobotClient("127.0.0.1", port) as robot:
            res = await robot.cmdexec(Break())
    assert res.messages[0].ok
    s = robot.stats
    assert (s.unknown_acks, s.unroutable_errors, s.bad_lines, s.acks) == (1, 1, 2, 1)
    assert [kind for _, kind, _ in s.unexpected] == ["unknown_ack", "unroutable_error", "bad_line", "oversize"]


# ------------------------------------------------------------------------------------------------ lifecycle
@pytest.mark.timeout(10)
async def test_connect_refused_is_connect_error_and_state_errors():
    async with ScriptedServer() as server:
        port = server.port
    robot = RobotClient("127.0.0.1", port, connect_timeout_s=2.0)
    with pytest.raises(ConnectError):
        await robot.connect()
    with pytest.raises(ClientStateError):
        await robot.cmdexec(Break())
    async with ScriptedServer() as server:
        robot = RobotClient(server.host, server.port)
        async with robot:
            with pytest.raises(ClientStateError):
                async with robot:
                    pass
            with pytest.raises(ClientStateError):
                await robot.connect()
            assert robot.connected
        assert robot.state.value == "closed"
        async with robot:  # reusable
            assert (await robot.cmdexec(Break())).messages[0].ok


@pytest.mark.timeout(10)
async def test_close_fails_pending_submissions_with_connection_lost():
    async with ScriptedServer(silent_after=1) as server:
        robot = RobotClient(server.host, server.port)
        await robot.connect()
        sub = robot.submit(SetSpeed(10), Break())
        await server.wait_connections(1)
        waiter = asyncio.create_task(sub.wait(timeout_s=5))
        await robot.close()
        with pytest.raises(ConnectionLost) as info:
            await waiter
    assert info.value.unresolved == sub.ids and info.value.acked == ()
    assert robot.pending_ids == ()


@pytest.mark.timeout(10)
async def test_observers_get_write_and_read_times_and_batches_and_failures_are_contained():
    rec = Recorder()

    class Broken:
        def on_send(self, msg):
            raise RuntimeError("observer bug")

        def on_ack(self, result):
            raise RuntimeError("observer bug")

    async with ScriptedServer() as server:
        async with RobotClient(server.host, server.port, observers=[Broken()]) as robot:
            robot.add_observer(rec)
            await robot.cmdexec(SetSpeed(10), MoveToolZ(1))
            await robot.cmdexec_joined(SetSpeed(10), MoveToolZ(1))
            sub = robot.submit(Break())
            await sub.wait()
    assert [m.batch for m in rec.sent] == [1, 2, 2, 3, 3, 3, 4]
    assert [m.skill for m in rec.sent] == ["set_speed", "move_rel_tool", "break"] * 2 + ["break"]
    assert [a.id for a in rec.acks] == [m.id for m in rec.sent]
    for sent, got in zip(rec.sent, rec.acks, strict=True):
        assert got.t_send_s == sent.t_send_s <= got.t_recv_s
        assert got.args == sent.args and got.batch == sent.batch
    assert rec.acks[1].ack.pose == server.pose


# ------------------------------------------------------------------------------------------------ uvloop
def _scenario():
    async def run():
        rec = Recorder()
        async with ScriptedServer({"break": Reply(delay_s=5.0), "move_to": Reply.error(-610, "out of range")}) \
                as server:
            async with RobotClient(server.host, server.port, observers=[rec]) as robot:
                joined = await robot.cmdexec_joined(SetSpeed(20), MoveToolZ(2.5, break_move=False))
                with pytest.raises(CommandError):
                    await robot.cmdexec(MoveTo([1, 2, 3, 4, 5, 6], break_move=False))
                rec.forget("move_rel_tool")
                task = asyncio.create_task(robot.cmdexec(MoveToolZ(1)))
                await rec.acked("move_rel_tool")
                await robot.stop()
                with pytest.raises(CommandAborted):
                    await task
                pending_after_stop = robot.pending_ids
            # connection loss and explicit reconnect on this loop too
            async with ScriptedServer(drop_after=2) as dropper:
                async with RobotClient(dropper.host, dropper.port) as robot:
                    with pytest.raises(ConnectionLost) as info:
                        await robot.cmdexec_joined(SetSpeed(1), SetSpeed(2))
                    assert len(info.value.acked) == 1 and len(info.value.unresolved) == 1
                    dropper.drop_after = None
                    await robot.connect()
                    assert (await robot.cmdexec(Break())).messages[0].ok
            return [m.skill for m in joined], pending_after_stop, type(asyncio.get_running_loop()).__module__
    return run


@pytest.mark.timeout(15)
@pytest.mark.parametrize("loop_name", ["asyncio", "uvloop"])
def test_same_behaviour_on_asyncio_and_uvloop(loop_name):
    if loop_name == "uvloop":
        uvloop = pytest.importorskip("uvloop")
        factory = uvloop.new_event_loop
    else:
        factory = asyncio.new_event_loop
    with asyncio.Runner(loop_factory=factory) as runner:
        skills, pending, loop_module = runner.run(_scenario()())
    assert skills == ["set_speed", "move_rel_tool"]
    assert pending == ()
    assert loop_module.startswith("uvloop" if loop_name == "uvloop" else "asyncio")


@pytest.mark.timeout(10)
async def test_scripted_server_close_right_after_accept_drops_the_connection():
    # A connection accepted just before close() must not be left open (its handler had not started yet).
    for _ in range(5):
        server = await ScriptedServer(silent_after=1).start()
        robot = RobotClient(server.host, server.port)
        await robot.connect()
        sub = robot.submit(Break())
        await server.close()
        with pytest.raises(ConnectionLost) as info:
            await sub.wait(timeout_s=3)
        assert info.value.unresolved == sub.ids
        await robot.close()


@pytest.mark.timeout(10)
async def test_oversize_command_line_gets_an_error_ack_with_its_id():
    # A client bypassing validation (raw write) sends a 200-character line; the error ack carries the ID.
    async with ScriptedServer() as server:
        reader, writer = await asyncio.open_connection(server.host, server.port)
        writer.write(b"0000abcd:set_speed:" + b"1" * 200 + b"\r\n0000abce:break\r\n")
        ack_reader = AckReader()
        acks: list[Ack] = []
        while len(acks) < 2:
            acks += ack_reader.acks(await reader.read(4096))
        writer.close()
        await writer.wait_closed()
    first, second = acks
    assert (first.id, first.status, first.error_code) == ("0000abcd", Status.ERROR, -402)
    assert (second.id, second.status) == ("0000abce", Status.DONE)


@pytest.mark.timeout(10)
async def test_a_refused_connection_says_why_in_connection_lost():
    from aioadept import Here
    from aioadept.testing.sim import running_sim

    async with running_sim(instant=True, max_clients=1) as sim, RobotClient(sim.host, sim.port) as first:
        await first.here()
        async with RobotClient(sim.host, sim.port) as refused:
            with pytest.raises(ConnectionLost) as info:
                await refused.cmdexec(Here())
            # Whether the refusal arrived before or after the command was written, both errors say why.
            with pytest.raises(ConnectionLost) as again:
                await refused.cmdexec(Here())
    said = re.compile(r"too many clients[^(]*\(code -530\)")  # the server may add how it still serves stop
    assert said.search(str(info.value))
    assert said.search(str(again.value)) and "nothing was sent" in str(again.value)
