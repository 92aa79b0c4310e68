"""A client that never finishes its line loses its connection (and its slot); others are not affected."""

from __future__ import annotations

import asyncio

import pytest

from aioadept.client import RobotClient
from aioadept.protocol import NO_ID, ErrorCode, Status, parse_ack
from aioadept.testing.sim import running_sim

pytestmark = pytest.mark.timeout(20)


async def test_a_trickled_incomplete_line_is_closed_after_the_line_timeout_from_its_first_byte():
    async with running_sim(instant=True, line_timeout_s=0.5, max_clients=1) as sim:
        reader, writer = await asyncio.open_connection(sim.host, sim.port)
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        # One byte every 0.1 s until 0.4 s: if each byte restarted the clock, the cut would come at 0.9 s.
        for b in b"0000a":
            writer.write(bytes([b]))
            await writer.drain()
            await asyncio.sleep(0.1)
        data = await asyncio.wait_for(reader.read(), 5)
        elapsed = loop.time() - t0
        writer.close()
        ack = parse_ack(data.rstrip(b"\r\n"))
        assert ack.status is Status.ERROR and ack.id == NO_ID
        assert ack.error_code == ErrorCode.MALFORMED_MESSAGE and "not completed" in ack.error_message
        assert 0.5 <= elapsed < 0.85
        # The slot is free again: with max_clients=1 a new client is served.
        async with RobotClient(sim.host, sim.port) as rc:
            assert (await rc.here()) == sim.controller.here


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
