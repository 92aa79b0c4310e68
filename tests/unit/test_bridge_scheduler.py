"""The bridge's one-writer scheduler (aioadept.bridge.node.Bridge) without Zenoh: queries are handed to it as the
Zenoh callback would hand them to the loop, the controller is a ScriptedServer in memory, and what reached the
controller is read from the server's record. The same rules run end to end in tests/integration/test_bridge.py."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field

import pytest

from aioadept.bridge.node import Bridge
from aioadept.bridge.wire import MAX_QUEUED_PER_APP, parse_failure
from aioadept.client import RobotClient
from aioadept.protocol import parse_ack
from aioadept.testing import Reply, ScriptedServer


@dataclass
class _Bytes:
    data: bytes

    def to_bytes(self) -> bytes:
        return self.data


@dataclass
class FakeQuery:
    """What the bridge uses of a ``zenoh.Query``."""

    payload: _Bytes
    attachment: _Bytes | None
    answer: asyncio.Future = field(default_factory=lambda: asyncio.get_running_loop().create_future())

    def reply(self, key: str, payload: bytes) -> None:
        self.answer.set_result(("ok", payload))

    def reply_err(self, payload: bytes) -> None:
        self.answer.set_result(("err", payload))

    def drop(self) -> None:
        pass


def query(app: str, *lines: str) -> FakeQuery:
    return FakeQuery(_Bytes("".join(f"{line}\r\n" for line in lines).encode()), _Bytes(app.encode()))


async def started(bridge: Bridge) -> asyncio.Task[None]:
    bridge._loop = asyncio.get_running_loop()
    return asyncio.create_task(bridge._pump())


async def outcome(q: FakeQuery):
    kind, payload = await asyncio.wait_for(q.answer, 5)
    return (kind, [parse_ack(line) for line in payload.split(b"\r\n") if line]) if kind == "ok" else (kind,
                                                                                            parse_failure(payload))


@pytest.mark.timeout(10)
async def test_batches_run_one_at_a_time_in_arrival_order_with_the_applications_ids_mapped_back():
    server = ScriptedServer({"move_joints": Reply(delay_s=0.05)})
    robot = RobotClient(connector=server.connector(), stop_port=None)
    bridge = Bridge(robot)
    pump = await started(bridge)
    try:
        qs = [query("a", "00000001:move_joints:0,0,0,0,0,0"), query("b", "00000001:here"),
              query("a", "00000002:set_speed:5", "00000003:here")]
        for q in qs:
            bridge._on_query(q)
        results = [await outcome(q) for q in qs]
    finally:
        pump.cancel()
        await robot.close()
    assert [[a.id for a in acks] for _, acks in results] == [["00000001"], ["00000001"], ["00000002", "00000003"]]
    skills = [line.split(b":")[1] for line in server.lines()]
    assert skills == [b"move_joints", b"here", b"set_speed", b"here"]
    assert len({line.split(b":")[0] for line in server.lines()}) == 4     # the controller-side IDs are distinct


@pytest.mark.timeout(10)
async def test_a_stop_overtakes_every_queued_batch_which_is_never_sent():
    server = ScriptedServer({"move_joints": Reply(delay_s=2.0)})
    robot = RobotClient(connector=server.connector(), stop_port=None)
    bridge = Bridge(robot)
    pump = await started(bridge)
    try:
        moving = query("a", "00000001:move_joints:0,0,0,0,0,0")
        bridge._on_query(moving)
        await asyncio.sleep(0.05)             # on the controller now (the pump wrote it)
        queued = [query("a", "00000002:here"), query("b", "0000000a:move_joints:1,0,0,0,0,0")]
        for q in queued:
            bridge._on_query(q)
        stop = query("c", "0000beef:stop")
        bridge._on_query(stop)
        for q in queued:
            kind, failure = await outcome(q)
            assert kind == "err" and failure.kind == "aborted" and "'c'" in failure.text
        kind, acks = await outcome(stop)
        assert kind == "ok" and acks[0].id == "0000beef" and acks[0].ok
        kind, acks = await outcome(moving)
        assert kind == "ok" and acks[0].status.value == "aborted"     # the controller aborted it
    finally:
        pump.cancel()
        await robot.close()
    assert [line.split(b":")[1] for line in server.lines()] == [b"move_joints", b"stop"]
    assert bridge.stats.aborted_before_send == 2


@pytest.mark.timeout(10)
async def test_a_batch_taken_from_the_queue_while_the_link_reconnects_is_not_sent_after_a_stop():
    server = ScriptedServer()
    gate = asyncio.Event()
    inner = server.connector()

    async def slow_connect():
        await gate.wait()
        return await inner()

    robot = RobotClient(connector=slow_connect, stop_port=None)
    bridge = Bridge(robot)
    pump = await started(bridge)
    try:
        q = query("a", "00000001:move_joints:0,0,0,0,0,0")
        bridge._on_query(q)
        await asyncio.sleep(0.05)             # the pump took it and waits for the connection
        assert not bridge._jobs and bridge._current is not None
        stop = query("b", "00000002:stop")
        bridge._on_query(stop)
        gate.set()
        kind, failure = await outcome(q)
        assert kind == "err" and failure.kind == "aborted"
        await outcome(stop)                   # answered (the link was not up when it came: an error here)
    finally:
        pump.cancel()
        await robot.close()
    assert b"move_joints" not in b"".join(server.lines())


@pytest.mark.timeout(10)
async def test_a_vanished_application_loses_its_queued_batches_only_and_the_busy_limit_is_per_application():
    server = ScriptedServer({"move_joints": Reply(delay_s=0.3)})
    robot = RobotClient(connector=server.connector(), stop_port=None)
    bridge = Bridge(robot)
    pump = await started(bridge)
    try:
        first = query("a", "00000001:move_joints:0,0,0,0,0,0")
        bridge._on_query(first)
        await asyncio.sleep(0.05)
        mine = [query("a", f"{n + 2:08x}:here") for n in range(MAX_QUEUED_PER_APP + 1)]
        theirs = query("b", "00000001:here")
        for q in (*mine, theirs):
            bridge._on_query(q)
        kind, failure = await outcome(mine[-1])
        assert kind == "err" and failure.kind == "busy"
        bridge._on_presence("a", False)
        for q in mine[:-1]:
            kind, failure = await outcome(q)
            assert kind == "err" and failure.kind == "dropped"
        assert (await outcome(first))[0] == "ok"        # already on the controller: runs to its end
        assert (await outcome(theirs))[0] == "ok"
    finally:
        pump.cancel()
        await robot.close()
    assert [line.split(b":")[1] for line in server.lines()] == [b"move_joints", b"here"]
    assert bridge.stats.dropped_vanished == MAX_QUEUED_PER_APP and bridge.stats.busy == 1


@pytest.mark.timeout(10)
async def test_a_malformed_query_is_answered_and_changes_nothing():
    server = ScriptedServer()
    robot = RobotClient(connector=server.connector(), stop_port=None)
    bridge = Bridge(robot)
    pump = await started(bridge)
    try:
        bad = FakeQuery(_Bytes(b"nonsense\r\n"), _Bytes(b"a"))
        bridge._on_query(bad)
        kind, failure = await outcome(bad)
        ok = query("a", "00000001:here")
        bridge._on_query(ok)
        assert (await outcome(ok))[0] == "ok"
    finally:
        pump.cancel()
        await robot.close()
    assert kind == "err" and failure.kind == "malformed" and "line 1" in failure.text
    assert [line.split(b":")[1] for line in server.lines()] == [b"here"]


@pytest.mark.timeout(10)
async def test_closing_the_bridge_answers_the_batch_in_flight_as_unknown_and_the_queued_as_not_sent():
    server = ScriptedServer({"move_joints": Reply(delay_s=2.0)})
    robot = RobotClient(connector=server.connector(), stop_port=None)
    bridge = Bridge(robot)
    bridge._tasks.append(await started(bridge))
    moving = query("a", "00000001:move_joints:0,0,0,0,0,0")
    bridge._on_query(moving)
    await asyncio.sleep(0.05)
    queued = query("b", "00000001:here")
    bridge._on_query(queued)
    await bridge.aclose()
    kind, failure = await outcome(moving)
    assert kind == "err" and failure.kind == "lost" and failure.unresolved == ("00000001",)
    kind, failure = await outcome(queued)
    assert kind == "err" and failure.kind == "closed" and failure.unresolved == ()
    assert [line.split(b":")[1] for line in server.lines()] == [b"move_joints"]
