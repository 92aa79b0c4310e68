"""The line timeout cuts only the stuck (docs/security.md, "Safety promises"), on every backend, over real TCP.

A connection of the main port that has sent part of a line and then nothing for the line timeout is refused
(-401, ID 00000000) and closed; a line sent in slow fragments, each within the timeout, is served; a client idle
between commands longer than the timeout is still served. The sim is started with ``--line-timeout``, the V+
server with ``rs.lntmo`` in its rsconfig.V2 (the same rule: from the last byte of an incomplete line).
"""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from aioadept.protocol import NO_ID, ErrorCode, Status

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
TIMEOUT_S = 0.5

pytestmark = pytest.mark.timeout(60)


def _with_line_timeout(backend: str, tmp_path: Path) -> tuple[str, ...]:
    """``aioadept sim`` options giving the backend a line timeout of TIMEOUT_S."""
    if backend == "python":
        return ("--line-timeout", str(TIMEOUT_S))
    cfg = (VPLUS / "rsconfig.V2").read_text()
    assert cfg.count("rs.lntmo = 10\n") == 1, "rsconfig.V2 no longer sets rs.lntmo = 10"
    (tmp_path / "rsconfig.V2").write_text(cfg.replace("rs.lntmo = 10\n", f"rs.lntmo = {TIMEOUT_S}\n"))
    return ("--vplus", str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(tmp_path / "rsconfig.V2"))


async def test_a_connection_stuck_mid_line_is_cut_after_the_timeout_from_its_last_byte(
        backend, start_server, tmp_path):
    async with start_server(backend, *_with_line_timeout(backend, tmp_path)) as server:
        c = await server.connect()
        loop = asyncio.get_running_loop()
        # A few fragments, then silence mid-line: the cut comes one timeout after the LAST byte.
        for b in b"0000a":
            c.writer.write(bytes([b]))
            await c.writer.drain()
            await asyncio.sleep(0.2)
        t_last = loop.time() - 0.2
        ack = await c.ack(timeout=10)
        assert ack.status is Status.ERROR and ack.id == NO_ID, ack
        assert ack.error_code == ErrorCode.MALFORMED_MESSAGE and "not completed" in ack.error_message, ack
        assert await asyncio.wait_for(c.reader.read(), 10) == b""      # and the connection is closed
        assert TIMEOUT_S - 0.05 <= loop.time() - t_last < 5.0
        await c.close()
        # the server goes on serving
        d = await server.connect()
        await d.send("0000abcf:here")
        assert (await d.ack()).status is Status.DONE
        await d.close()


async def test_a_line_sent_in_slow_fragments_and_a_client_idle_between_commands_are_not_cut(
        backend, start_server, tmp_path):
    async with start_server(backend, *_with_line_timeout(backend, tmp_path)) as server:
        c = await server.connect()
        # Each fragment well within the timeout, the whole line about two timeouts: a live client on a slow link.
        for part in (b"0000ab", b"cd:he", b"re", b"\r\n"):
            c.writer.write(part)
            await c.writer.drain()
            await asyncio.sleep(0.3)
        ack = await c.ack(timeout=10)
        assert (ack.id, ack.status) == ("0000abcd", Status.DONE), ack
        # Then idle between commands for several timeouts: still connected and served.
        await asyncio.sleep(4 * TIMEOUT_S)
        await c.send("0000abce:here")
        ack = await c.ack(timeout=10)
        assert (ack.id, ack.status) == ("0000abce", Status.DONE), ack
        await c.close()


async def test_a_trickle_that_never_ends_its_line_is_cut_after_six_timeouts(backend, start_server, tmp_path):
    async with start_server(backend, *_with_line_timeout(backend, tmp_path)) as server:
        c = await server.connect()
        loop = asyncio.get_running_loop()
        t0 = loop.time()

        async def trickle() -> None:
            try:
                while True:
                    c.writer.write(b"9")     # every 0.1 s: never idle for a timeout, never a delimiter
                    await c.writer.drain()
                    await asyncio.sleep(0.1)
            except OSError:
                return

        feeder = asyncio.create_task(trickle())
        try:
            ack = await c.ack(timeout=20)
        finally:
            feeder.cancel()
            await asyncio.gather(feeder, return_exceptions=True)
        assert ack.status is Status.ERROR and ack.error_code == ErrorCode.MALFORMED_MESSAGE, ack
        assert 6 * TIMEOUT_S - 0.05 <= loop.time() - t0 < 15
        await c.close()
