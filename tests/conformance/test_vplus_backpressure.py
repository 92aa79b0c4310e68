"""The shipped V+ server with clients that stop reading their acks, on small socket buffers as a controller's.

The emulator runs with ``--tcp-send-buffer 4096`` (docs/vplus.md, "Line coverage of vplus/"): a client that does
not read backs the server's output up after ~16 KiB, so the paths of "A client that does not read" (docs/vplus.md,
"Tasks and shared state") run for real: ``rs.canput``, ``rs.drop``, ``rs.flushout`` and ``rs.rdack`` with the
output not going out, and with ``rs.closeh = FALSE`` the stop port's reopening (``rs.sreopen``). What the server
promises there, checked here:

- a client that does not read is dropped (its connection reset), whether it floods or trickles, and never the
  others: their acks go on;
- a stop from another client is acked within its bound while that client's output is backed up, and nothing moves
  after it;
- with ``rs.closeh = FALSE`` the client is only ignored, its port's acks wait until it goes, but a stop on that port
  still brakes the arm at once (with the reader's ring full of that port's answers too), and the stop port's answers
  and a stop through it are acked; once it goes, the acks owed come;
- a full command queue refuses lines with -530 and keeps its last entries for stops.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from aioadept.geometry import poses_close
from aioadept.ports import free_port
from aioadept.protocol import Ack, ErrorCode, Status, parse_ack
from aioadept.robots import DEFAULT_MODEL
from aioadept.testing.nodes import running_node
from modelarm import Arm

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
ARM = Arm.named(DEFAULT_MODEL)
QCAP, QRES = 128, 16   # the command ring's entries and those kept for stops (rs.qcap, rs.qres in rserver.V2)


class Conn:
    """A protocol connection that reads: send lines, read acks."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer

    @classmethod
    async def to(cls, port: int) -> Conn:
        return cls(*await asyncio.open_connection("127.0.0.1", port))

    def send(self, *lines: str) -> None:
        self.writer.write(b"".join(ln.encode() + b"\r\n" for ln in lines))

    async def ack(self, timeout: float = 15.0) -> Ack:
        return parse_ack((await asyncio.wait_for(self.reader.readuntil(b"\r\n"), timeout))[:-2])

    async def acks(self, n: int, timeout: float = 15.0) -> list[Ack]:
        return [await self.ack(timeout) for _ in range(n)]

    async def until(self, id_: str, timeout: float = 15.0) -> tuple[Ack, list[Ack]]:
        """Read acks until ``id_``'s: (its ack, the acks before it)."""
        before = []
        async with asyncio.timeout(timeout):
            while (a := await self.ack(timeout)).id != id_:
                before.append(a)
        return a, before


class Mute:
    """A client that sends ``here`` lines and never reads: a small receive window, so its acks back up soon."""

    def __init__(self, port: int) -> None:
        self.sock = socket.socket()
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)   # before connect: the window stays small
        self.sock.connect(("127.0.0.1", port))
        self.sock.setblocking(False)
        self.sent = 0
        self.out = b""

    async def send_until_reset(self, batch: int, every_s: float, timeout: float = 20.0) -> bool:
        """Send ``batch`` lines every ``every_s`` s until the server resets the connection (True), or timeout."""
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(timeout):
                while True:
                    if not self.out:
                        self.out = b"".join(b"%08x:here\r\n" % (0x20000000 + self.sent + i) for i in range(batch))
                        self.sent += batch
                    try:
                        self.out = self.out[self.sock.send(self.out):]
                    except BlockingIOError:
                        pass
                    except (ConnectionResetError, BrokenPipeError):
                        return True
                    await asyncio.sleep(every_s)
        return False

    def reset(self) -> None:
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        self.sock.close()   # RST: what a killed client sends


@contextlib.asynccontextmanager
async def vplus_server(tmp_path: Path, *, closeh: bool = True) -> AsyncIterator[tuple[int, int, Path]]:
    """The shipped server on the emulator with 4 KiB socket buffers: (its port, its stop port, its log)."""
    cfg = (VPLUS / "rsconfig.V2").read_text()
    if not closeh:
        assert "rs.closeh = TRUE" in cfg
        cfg = cfg.replace("rs.closeh = TRUE", "rs.closeh = FALSE")
    (tmp_path / "rsconfig.V2").write_text(cfg)
    files = [str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(tmp_path / "rsconfig.V2")]
    port, sport = free_port(), free_port()
    while sport == port:
        sport = free_port()
    log = tmp_path / "sim.log"
    async with running_node("sim", "--vplus", *files, "--run", "rs.main", "--map-port", f"1234={port}",
                            "--map-port", f"1235={sport}", "--state-endpoint", "none", "--tcp-send-buffer", "4096",
                            log_path=log, ready_timeout_s=60, expect_clean_exit=False):
        async with asyncio.timeout(20):
            while True:   # the stop port opens a moment after the READY of the first
                try:
                    _, w = await asyncio.open_connection("127.0.0.1", sport)
                    w.close()
                    break
                except OSError:
                    await asyncio.sleep(0.05)
        yield port, sport, log


async def _start_moving(b: Conn, tag: str) -> None:
    b.send(f"{tag}000001:set_speed:{ARM.speed(10)}", f"{tag}000002:move_joints:{ARM.j1_wire(60)}")
    assert [a.status for a in await b.acks(2)] == [Status.DONE, Status.DONE]   # acked as the motion starts


async def _at_rest(c: Conn, tag: str) -> None:
    """Two heres 0.5 s apart give the same pose: nothing moves."""
    c.send(f"{tag}000001:here")
    first = (await c.ack()).pose
    await asyncio.sleep(0.5)
    c.send(f"{tag}000002:here")
    assert poses_close((await c.ack()).pose, first, tol_mm=0.01, tol_deg=0.01), "the arm moved after the stop"


async def _timed_stop(c: Conn, sid: str) -> float:
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    c.send(f"{sid}:stop")
    ack, _ = await c.until(sid, 10)
    assert ack.status is Status.DONE, ack
    return loop.time() - t0


@pytest.mark.timeout(90)
async def test_clients_that_do_not_read_are_dropped_and_never_hold_up_another_clients_stop_or_acks(tmp_path):
    async with vplus_server(tmp_path) as (port, sport, log):
        b = await Conn.to(port)
        await _start_moving(b, "ba")
        # a flood that never reads: dropped (reset) once its acks back up; meanwhile b's stop is acked at once
        flood = Mute(port)
        dropping = asyncio.ensure_future(flood.send_until_reset(100, 0.005))
        while flood.sent < 400 and not dropping.done():
            await asyncio.sleep(0.005)
        waited = await _timed_stop(b, "ba000003")
        assert waited < 2.0, f"stop acked after {waited:.2f} s with a client not reading its acks"
        assert await dropping, "a client that floods and never reads was not dropped"
        await _at_rest(b, "bb")
        # a client that trickles lines and never reads: dropped too, and b's acks keep coming meanwhile
        trickle = Mute(port)
        dropping = asyncio.ensure_future(trickle.send_until_reset(4, 0.02))
        loop = asyncio.get_running_loop()
        n = 0
        while not dropping.done():
            t0 = loop.time()
            b.send(f"bc{n:06d}:here")
            assert (await b.ack(5)).status is Status.DONE
            assert loop.time() - t0 < 2.0, "another client's ack waited behind the one not reading"
            n += 1
            await asyncio.sleep(0.02)
        assert await dropping, "a client that trickles lines and never reads was not dropped"
        assert "dropping client" in log.read_text()
        # the same on the stop port (it answers here): dropped, and the port serves the next stop
        smute = Mute(sport)
        assert await smute.send_until_reset(4, 0.02), "a stop-port client that never reads was not dropped"
        s = await Conn.to(sport)
        assert await _timed_stop(s, "bs000001") < 2.0
        s.writer.close()
        # a full command queue: b's break waits for a move; c and d queue 64 each; the queue keeps its last 16
        # entries for stops, so d's lines beyond 127 - 16 = 111 in all are refused with -530 and never run
        b.send(f"bd000000:set_speed:{ARM.speed(2)}", f"bd000001:move_joints:{ARM.j1_wire(-60)}", "bd000002:break")
        assert [a.status for a in await b.acks(2)] == [Status.DONE] * 2   # the move started: the break now waits
        c, d = await Conn.to(port), await Conn.to(port)
        c.send(*[f"cq{i:06d}:set_speed:{ARM.speed(10)}" for i in range(64)])
        await asyncio.sleep(0.1)
        d.send(*[f"dq{i:06d}:set_speed:{ARM.speed(10)}" for i in range(64)])
        refused = []
        async with asyncio.timeout(10):
            while len(refused) < 64 - (QCAP - 1 - QRES - 64):
                a = await d.ack()
                assert (a.status, a.error_code) == (Status.ERROR, ErrorCode.SERVER_BUSY), a
                refused.append(a.id)
        assert refused == [f"dq{i:06d}" for i in range(64 - len(refused), 64)], refused
        # a stop still gets in, and every admitted line is aborted: none of them runs
        waited = await _timed_stop(b, "bd000003")
        assert waited < 2.0, waited
        for conn, tag, n_admitted in ((c, "cq", 64), (d, "dq", 64 - len(refused))):
            acks = await conn.acks(n_admitted)
            assert {(a.id[:2], a.status) for a in acks} == {(tag, Status.ABORTED)}, acks[:3]
        for conn in (b, c, d):
            conn.writer.close()


@pytest.mark.timeout(90)
async def test_without_closeh_a_client_not_reading_is_ignored_and_stops_still_brake_and_are_acked(tmp_path):
    async with vplus_server(tmp_path, closeh=False) as (port, sport, log):
        b = await Conn.to(port)
        await _start_moving(b, "ea")
        mute = Mute(port)
        # it is dropped from the server's view (ignored, rs.sgone) but its connection stays open: no reset
        assert not await mute.send_until_reset(100, 0.005, timeout=3.0)
        assert "dropping client" in log.read_text()
        # its port's answers wait behind its output: another client's 80 heres there fill the reader's ring,
        # which must not stop the reader; b's stop there still brakes the arm at once
        c = await Conn.to(port)
        c.send(*[f"ca{i:06d}:here" for i in range(80)])
        await asyncio.sleep(0.2)
        b.send("ea000003:stop")
        s = await Conn.to(sport)
        await asyncio.sleep(0.3)   # the deceleration (~0.1 s)
        await _at_rest(s, "eb")
        # and a stop through the stop port (a LUN of its own) is acked within its bound
        waited = await _timed_stop(s, "eb000003")
        assert waited < 2.0, waited
        # once the client not reading goes, the acks owed on its port come, in order
        b.send("ea000004:here")
        mute.reset()
        stop, before = await b.until("ea000003", 5)
        assert stop.status is Status.DONE and before == [], before
        assert (await b.ack(5)).id == "ea000004"
        # an idle stop-port connection is closed after rs.stmo (1 s): without closeh by reopening the port,
        # which a newcomer's stop then reaches
        assert await asyncio.wait_for(s.reader.read(), 5) == b""
        async with asyncio.timeout(10):
            while True:
                try:
                    s2 = await Conn.to(sport)
                    waited = await _timed_stop(s2, "ec000001")
                    break
                except (OSError, asyncio.IncompleteReadError):
                    await asyncio.sleep(0.05)
        assert waited < 2.0, waited
        for conn in (b, c, s2):
            conn.writer.close()
