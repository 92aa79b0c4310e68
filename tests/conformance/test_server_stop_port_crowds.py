"""A newcomer's stop gets in past a crowd on the stop port, on both backends (docs/protocol.md 4.2.1).

Every main-port slot is held by idle connections (one of them moving the arm slowly), and the stop port is crowded by
a real process (aioadept.testing.crowds): well-behaved monitors polling ``here`` every 0.5 s on every one of its
slots, slowloris peers that reconnect the moment they are dropped, or a storm of short connections (each stays
0.5 s). A newcomer connects to the stop port and sends
``stop`` (trying again if it is turned away, as an operator's tool does): it is acked ``done`` promptly and the arm
is at rest. (The V+ server once let the monitors keep every stop-port slot for good: the stop never got in; with
the slowloris peers it took about 0.8 s, with the storm up to seconds.)
"""

from __future__ import annotations

import asyncio
import contextlib
import sys

import pytest

from aioadept.geometry import poses_close
from aioadept.protocol import parse_ack
from aioadept.testing.crowds import stop_through

CROWDS = {"monitors": 4, "slowloris": 6, "storm": 8}  # the V+ server's stop port has rs.smaxcli = 4 slots


@contextlib.asynccontextmanager
async def _crowd(kind: str, host: str, port: int, n: int):
    proc = await asyncio.create_subprocess_exec(sys.executable, "-m", "aioadept.testing.crowds", kind, host,
                                                str(port), str(n), stdout=asyncio.subprocess.PIPE)
    try:
        assert proc.stdout is not None
        line = await asyncio.wait_for(proc.stdout.readline(), 30)
        assert line.startswith(b"READY"), line
        await asyncio.sleep(1.5)  # past the stop port's idle time: the crowd has settled in
        yield proc
    finally:
        proc.kill()
        await proc.wait()


async def _here(reader: asyncio.StreamReader, writer: asyncio.StreamWriter, mid: str):
    """The pose from a ``here`` on the mover's own connection (its earlier acks are skipped)."""
    writer.write(f"{mid}:here\r\n".encode())
    async with asyncio.timeout(10):
        while True:
            ack = parse_ack((await reader.readuntil(b"\r\n"))[:-2])
            if ack.id == mid:
                return ack.pose


@pytest.mark.parametrize("kind", sorted(CROWDS))
@pytest.mark.parametrize("backend", ["python", "vplus"])
@pytest.mark.timeout(120)
async def test_a_newcomers_stop_gets_in_past_a_crowd_on_the_stop_port(backend, kind, start_server, arm):
    extra = ("--max-clients", "4") if backend == "python" else ()
    async with start_server(backend, *extra) as server:
        held = [await asyncio.open_connection(server.host, server.port) for _ in range(4 if backend == "python"
                                                                                     else 10)]
        reader, mover = held[0]
        async with _crowd(kind, server.host, server.stop_port, CROWDS[kind]):
            for i in range(3):
                # J1 by 60 deg at 10 % (the s850's rate on every model): seconds
                target = arm.j1_wire(60) if i % 2 == 0 else arm.home_wire
                mover.write(f"kw{i:06d}:set_speed:{arm.speed(10)}\r\nkx{i:06d}:move_joints:{target}\r\n".encode())
                await mover.drain()
                await asyncio.sleep(0.3)  # moving
                # The goal is 100 ms at p95 (benchmarks/bench_safety.py; 9-18 ms here alone and beside two CPU
                # hogs; up to 0.91 s seen under two test processes, cause not found). The bound catches what this
                # test is for: a stop that never gets in past the crowd, or takes seconds.
                took = await stop_through(server.host, server.stop_port, within_s=5.0)
                assert took < 1.5, f"{kind}: stop acked after {took:.2f} s"
                a = await _here(reader, mover, f"ky{i:06d}")
                await asyncio.sleep(0.3)
                assert poses_close(await _here(reader, mover, f"kz{i:06d}"), a, tol_mm=0.01, tol_deg=0.01), \
                    "the arm moved after the stop"
        for _, w in held:
            w.close()

