"""RobotClient keeps below the server's queue limit (64 per connection): a write that would leave more messages
pending is refused whole, before anything is sent, so a long pipelined sequence is never cut in its middle by the
server's -530 refusals while the rest of it runs. A stop is never refused. No sockets: in-memory streams."""

from __future__ import annotations

import asyncio

import pytest

from aioadept import Break, SetSpeed
from aioadept.client import RobotClient
from aioadept.defaults import MAX_QUEUED
from aioadept.errors import ClientStateError, TooManyPending
from aioadept.testing import ScriptedServer


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "64"])
def test_max_pending_must_be_a_positive_int_or_none(bad):
    with pytest.raises(ValueError, match="^max_pending"):
        RobotClient(max_pending=bad)
    assert RobotClient().max_pending == MAX_QUEUED == 64
    assert RobotClient(max_pending=None).max_pending is None


@pytest.mark.timeout(10)
async def test_a_write_beyond_the_limit_is_refused_whole_and_nothing_is_sent():
    server = ScriptedServer(silent_after=0)  # acks nothing: every message stays pending
    try:
        async with RobotClient(connector=server.connector(), max_pending=8) as robot:
            first = robot.submit(*[Break()] * 6)
            with pytest.raises(TooManyPending) as info:
                await robot.cmdexec_joined(SetSpeed(10), Break(), SetSpeed(20))  # 6 + 3 > 8
            assert (info.value.pending, info.value.wanted, info.value.limit) == (6, 3, 8)
            assert isinstance(info.value, ClientStateError) and "nothing was sent" in str(info.value)
            second = robot.submit(Break(), Break())  # 6 + 2 = 8: still admitted
            await asyncio.sleep(0.05)
            assert len(server.lines()) == 8, "the refused batch wrote nothing, not even its first messages"
            # The stop always goes out, whatever is pending (its ack never comes from this silent server).
            stop = robot.stop_nowait(timeout_s=0.2)
            await asyncio.sleep(0.05)
            assert server.lines()[-1].endswith(b":stop")
            stop.cancel()
            for sub in (first, second):
                sub.cancel()
    finally:
        await server.close()


@pytest.mark.timeout(10)
async def test_no_limit_with_none():
    server = ScriptedServer(silent_after=0)
    try:
        async with RobotClient(connector=server.connector(), max_pending=None) as robot:
            sub = robot.submit(*[Break()] * 200)
            await asyncio.sleep(0.05)
            assert len(server.lines()) == 200
            sub.cancel()
    finally:
        await server.close()
