"""The client's collaborators, each alone: its frozen options, the sans-IO deadline queue of its watchdog, the stop
on the stop port and the race of that stop with the main connection's. The deadline queue is driven with times
passed in; the stop port is a real asyncio server on 127.0.0.1."""

from __future__ import annotations

import asyncio
import dataclasses
import socket
import struct

import pytest

from aioadept import RobotClient
from aioadept.client.deadlines import DeadlineQueue
from aioadept.client.options import ClientOptions
from aioadept.client.ready import ReadyAttempts
from aioadept.client.stopport import drop_unsent_on_close, open_side_socket, race_stop, stop_on_port
from aioadept.errors import AckTimeout, CommandError, ConnectError, ConnectionLost
from aioadept.ports import free_port


# ------------------------------------------------------------------------------------------------ options
def test_options_are_frozen_checked_and_normalised():
    opts = ClientOptions(port=4000, ack_timeout_s=2, observers=[1, 2])
    assert opts.ack_timeout_s == 2.0 and isinstance(opts.ack_timeout_s, float) and opts.observers == (1, 2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.port = 1  # type: ignore[misc]
    for bad, match in ((dict(port=70000), "^port"), (dict(id_start=0), "^id_start"),
                       (dict(max_pending=0), "^max_pending"), (dict(stop_port=True), "^stop_port"),
                       (dict(stop_timeout_s=None), "^stop_timeout_s"), (dict(hello_timeout_s=-1), "^hello_timeout_s"),
                       (dict(max_line=0), "^max_line")):
        with pytest.raises(ValueError, match=match):
            ClientOptions(**bad)


def test_the_stop_port_number_follows_port_and_connector():
    assert ClientOptions(port=1234).stop_port_number == 1235
    assert ClientOptions(port=0).stop_port_number is None and ClientOptions(port=0xFFFF).stop_port_number is None
    assert ClientOptions(port=1234, stop_port=4100).stop_port_number == 4100
    assert ClientOptions(port=1234, stop_port=None).stop_port_number is None

    async def connector():  # pragma: no cover - never called
        raise AssertionError

    assert ClientOptions(port=1234, connector=connector).stop_port_number is None


def test_a_client_takes_options_or_keywords_and_its_settings_write_through():
    opts = ClientOptions("10.0.0.5", 4000, ack_timeout_s=3.0, max_pending=8)
    robot = RobotClient(options=opts)
    assert robot.options is opts and (robot.host, robot.port, robot.ack_timeout_s, robot.max_pending) == (
        "10.0.0.5", 4000, 3.0, 8)
    assert RobotClient("10.0.0.5", 4000, ack_timeout_s=3.0, max_pending=8).options == opts
    with pytest.raises(TypeError, match="either options= or"):
        RobotClient(port=4001, options=opts)
    robot.ack_timeout_s = 0.5
    assert robot.options.ack_timeout_s == 0.5 and opts.ack_timeout_s == 3.0  # a new value; the given one stands
    with pytest.raises(ValueError, match="^max_pending"):
        robot.max_pending = 0
    assert robot.max_pending == 8


# ----------------------------------------------------------------------------------------- deadline queue
class Wait:
    def __init__(self, name: str) -> None:
        self.name = name
        self._deadline = 0.0
        self._settled = False

    def __repr__(self) -> str:
        return self.name


def test_due_waits_come_out_in_order_and_settled_ones_never():
    q = DeadlineQueue()
    a, b, c = Wait("a"), Wait("b"), Wait("c")
    assert q.next_deadline is None and q.due(100.0) == []
    assert q.push(a, 10.0) and q.push(b, 10.0) and q.push(c, 12.0)
    assert q.next_deadline == 10.0 and len(q) == 3
    assert q.due(9.999) == []
    b._settled = True  # acked before its deadline
    assert q.due(10.0) == [a] and q.next_deadline == 12.0
    c._settled = True
    assert q.due(20.0) == [] and len(q) == 0 and q.next_deadline is None


def test_a_deadline_before_the_last_one_is_refused_for_a_timer_of_its_own():
    q = DeadlineQueue()
    a, b, c = Wait("a"), Wait("b"), Wait("c")
    assert q.push(a, 10.0)
    assert not q.push(b, 5.0)  # the default timeout was lowered: it must not wait behind a
    assert len(q) == 1 and q.due(5.0) == []
    a._settled = True
    assert q.push(c, 5.0)  # a left the front on the way: order holds again
    assert q.due(5.0) == [c]


# --------------------------------------------------------------------------------- wait_ready's schedule
def test_ready_attempts_back_off_doubling_up_to_the_cap_and_never_past_the_deadline():
    tries = ReadyAttempts("10.0.0.5:1234", 1.0, 0.15, now=100.0)
    assert tries.begin(100.0) == 1.0 and tries.attempts == 1
    assert [tries.pause(100.0) for _ in range(4)] == [0.05, 0.1, 0.15, 0.15]
    assert tries.begin(100.9) == pytest.approx(0.1)
    assert tries.pause(100.98) == pytest.approx(0.02)  # the deadline comes first


def test_ready_attempts_end_naming_the_attempts_and_the_last_failure():
    tries = ReadyAttempts("10.0.0.5:1234", 2.0, 1.0, now=0.0)
    tries.begin(0.0)
    tries.failed(ConnectError("connect to 10.0.0.5:1234: refused"), connected=False)
    assert tries.last == "ConnectError: connect to 10.0.0.5:1234: refused"
    tries.begin(1.0)
    tries.failed(TimeoutError(), connected=True)
    assert tries.last == "connected, but no answer to hello"
    tries.failed(AckTimeout("no ack", pending=("00000001",)), connected=False)
    assert tries.last == "connected, but no answer to hello"
    tries.failed(TimeoutError(), connected=False)
    with pytest.raises(ConnectError, match=r"^10.0.0.5:1234 not ready within 2 s \(2 attempts; last: no connection "
                                           r"before the deadline\)$"):
        tries.begin(2.0)


# -------------------------------------------------------------------------------------- the stop port
class StopPort:
    """A stop port on 127.0.0.1 answering each line with ``reply(id)`` (None: no answer)."""

    def __init__(self, reply) -> None:
        self.reply = reply
        self.lines: list[bytes] = []

    async def __aenter__(self) -> StopPort:
        self.port = free_port("127.0.0.1")
        self.server = await asyncio.start_server(self._serve, "127.0.0.1", self.port)
        return self

    async def __aexit__(self, *exc: object) -> None:
        self.server.close()
        await self.server.wait_closed()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        line = await reader.readline()
        self.lines.append(line)
        mid = line.split(b":")[0].decode()
        answer = self.reply(mid)
        if answer is not None:
            writer.write(b"garbage line\r\n" + answer.encode())
            await writer.drain()
            await reader.read()  # until the client closes
        else:
            await asyncio.sleep(5)
        writer.close()


DONE = "{}:done:1.000,1.100:100,0,500,180,0,0\r\n"


@pytest.mark.timeout(10)
async def test_stop_on_port_sends_one_stop_and_returns_on_done():
    sent, acked = [], []
    async with StopPort(DONE.format) as sp:
        res = await stop_on_port("127.0.0.1", sp.port, 2.0, on_send=sent.append, on_ack=acked.append)
    assert len(sp.lines) == 1 and sp.lines[0] == f"{res.id}:stop\r\n".encode()
    assert res.skill == "stop" and res.ack.ok and res.ack.pose.z == 500
    assert [m.id for m in sent] == [res.id] and acked == [res]


@pytest.mark.timeout(10)
async def test_stop_on_port_failures_are_named():
    async with StopPort(lambda mid: f"{mid}:error:1.000,1.000:0,0,0,0,0,0:-406:unknown skill\r\n") as sp:
        with pytest.raises(CommandError):
            await stop_on_port("127.0.0.1", sp.port, 2.0)
    async with StopPort(lambda mid: None) as sp:
        with pytest.raises(AckTimeout, match="no ack within 0.2 s"):
            await stop_on_port("127.0.0.1", sp.port, 0.2)
    with pytest.raises(ConnectError, match=f"stop port 127.0.0.1:{sp.port}"):
        await stop_on_port("127.0.0.1", sp.port, 2.0)  # nobody listens any more


async def _after(delay: float, result=None, exc: BaseException | None = None):
    await asyncio.sleep(delay)
    if exc is not None:
        raise exc
    return result


@pytest.mark.timeout(10)
async def test_race_the_main_path_alone_when_it_answers_in_time():
    started = []

    def side():
        started.append(1)
        return _after(0, "side")

    assert await race_stop(_after(0.01, "main"), side, 0.5, peer="p") == "main"
    assert started == []
    assert await race_stop(_after(0.01, "main"), None, 0.0, peer="p") == "main"


@pytest.mark.timeout(10)
async def test_race_the_stop_port_wins_when_the_main_path_is_slow_and_the_slow_one_is_cancelled():
    main = asyncio.ensure_future(_after(5, "main"))
    assert await race_stop(main, lambda: _after(0.01, "side"), 0.05, peer="p") == "side"
    await asyncio.sleep(0)
    assert main.cancelled()


@pytest.mark.timeout(10)
async def test_race_a_failure_counts_only_when_both_fail_and_then_the_main_one_is_raised():
    lost = ConnectionLost("lost", acked=(), unresolved=("00000001",))
    assert await race_stop(_after(0.05, exc=lost), lambda: _after(0.2, "side"), 0.01, peer="p") == "side"
    assert await race_stop(_after(0.2, "main"), lambda: _after(0, exc=ConnectError("refused")), 0.01,
                           peer="p") == "main"
    with pytest.raises(ConnectionLost) as info:
        await race_stop(_after(0.05, exc=lost), lambda: _after(0, exc=ConnectError("refused")),
                        0.01, peer="p")
    assert info.value is lost


@pytest.mark.timeout(10)
async def test_the_side_path_opens_a_connected_socket_and_the_old_connection_resets_on_close():
    accepted = asyncio.Event()

    async def serve(reader, writer):
        accepted.set()
        await reader.read()
        writer.close()

    port = free_port("127.0.0.1")
    server = await asyncio.start_server(serve, "127.0.0.1", port)
    try:
        side = await open_side_socket("127.0.0.1", port, 2.0)
        try:
            assert not side.getblocking() and side.getpeername() == ("127.0.0.1", port)
            await asyncio.wait_for(accepted.wait(), 2.0)
        finally:
            side.close()
        _, writer = await asyncio.open_connection("127.0.0.1", port)
        drop_unsent_on_close(writer.transport)
        linger = writer.get_extra_info("socket").getsockopt(socket.SOL_SOCKET, socket.SO_LINGER, 8)
        assert struct.unpack("ii", linger) == (1, 0)
        writer.transport.abort()
    finally:
        server.close()
        await server.wait_closed()
    with pytest.raises(OSError):
        await open_side_socket("127.0.0.1", port, 2.0)  # nobody listens any more
