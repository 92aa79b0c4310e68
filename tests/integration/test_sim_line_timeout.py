"""A client stuck in the middle of a line loses its connection (and its slot); a live one never does.

The line timeout runs from the last byte received while a line is incomplete (so a line sent in slow fragments is
served), a line's whole life is capped at LINE_MAX_FACTOR timeouts (so a trickle cannot hold a slot for ever), and a
client between lines is never timed (docs/security.md).
"""

from __future__ import annotations

import asyncio
import contextlib

import pytest

from aioadept.client import RobotClient
from aioadept.protocol import NO_ID, ErrorCode, Status, parse_ack
from aioadept.testing.sim import running_sim

pytestmark = pytest.mark.timeout(20)


async def read_refusal(reader) -> tuple:
    data = await asyncio.wait_for(reader.read(), 10)
    ack = parse_ack(data.rstrip(b"\r\n"))
    return ack


async def test_a_connection_stuck_mid_line_is_cut_after_the_timeout_from_its_last_byte():
    async with running_sim(instant=True, line_timeout_s=0.5, max_clients=1) as sim:
        reader, writer = await asyncio.open_connection(sim.host, sim.port)
        loop = asyncio.get_running_loop()
        # A few fragments, then silence mid-line: the cut comes one timeout after the LAST byte.
        for b in b"0000a":
            writer.write(bytes([b]))
            await writer.drain()
            await asyncio.sleep(0.1)
        t_last = loop.time() - 0.1
        ack = await read_refusal(reader)
        elapsed = loop.time() - t_last
        writer.close()
        assert ack.status is Status.ERROR and ack.id == NO_ID
        assert ack.error_code == ErrorCode.MALFORMED_MESSAGE and "not completed" in ack.error_message
        assert 0.45 <= elapsed < 3.0
        # The slot is free again: with max_clients=1 a new client is served.
        async with RobotClient(sim.host, sim.port) as rc:
            assert (await rc.here()) == sim.controller.here


async def test_a_line_sent_in_slow_fragments_is_served_not_cut():
    # Each fragment arrives well within the timeout, the whole line takes about three timeouts: a live client
    # on a slow link. (The first-byte rule cut it.)
    async with running_sim(instant=True, line_timeout_s=0.3) as sim:
        reader, writer = await asyncio.open_connection(sim.host, sim.port)
        for part in (b"0000ab", b"cd:mo", b"ve_joints:1", b"0,-90,180,", b"0,90,0\r", b"\n"):
            writer.write(part)
            await writer.drain()
            await asyncio.sleep(0.15)
        line = await asyncio.wait_for(reader.readline(), 5)
        ack = parse_ack(line.rstrip(b"\r\n"))
        assert (ack.id, ack.status) == ("0000abcd", Status.DONE)
        assert sim.controller.joints_deg[0] == pytest.approx(10.0)
        # Then idle between commands, longer than the timeout: still connected and served.
        await asyncio.sleep(0.5)
        writer.write(b"0000abce:here\r\n")
        line = await asyncio.wait_for(reader.readline(), 5)
        assert parse_ack(line.rstrip(b"\r\n")).status is Status.DONE
        writer.close()


async def test_a_trickle_that_never_ends_its_line_is_cut_after_the_line_cap():
    from aioadept.sim.server import LINE_MAX_FACTOR

    async with running_sim(instant=True, line_timeout_s=0.2) as sim:
        reader, writer = await asyncio.open_connection(sim.host, sim.port)
        loop = asyncio.get_running_loop()
        t0 = loop.time()

        async def trickle():
            with contextlib.suppress(OSError):
                while True:
                    writer.write(b"9")  # every 0.1 s: never idle for a timeout, never a delimiter
                    await writer.drain()
                    await asyncio.sleep(0.1)

        feeder = asyncio.create_task(trickle())
        try:
            ack = await read_refusal(reader)
        finally:
            feeder.cancel()
            await asyncio.gather(feeder, return_exceptions=True)
            writer.close()
        elapsed = loop.time() - t0
        assert ack.error_code == ErrorCode.MALFORMED_MESSAGE
        assert LINE_MAX_FACTOR * 0.2 - 0.05 <= elapsed < 10


async def test_complete_lines_written_slowly_are_not_cut():
    async with running_sim(instant=True, line_timeout_s=0.3) as sim:
        reader, writer = await asyncio.open_connection(sim.host, sim.port)
        for _ in range(3):
            writer.write(b"0000abcd:here\r\n")  # each line complete in one write
            await writer.drain()
            line = await asyncio.wait_for(reader.readline(), 5)
            assert parse_ack(line.rstrip(b"\r\n")).status is Status.DONE
            await asyncio.sleep(0.4)  # idle between lines is fine: only incomplete lines are timed
        writer.close()
