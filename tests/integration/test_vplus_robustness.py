"""The fuzz and fault suites' representative cases against the emulated ``vplus/`` server (fewer iterations):
``aioadept sim --vplus vplus/rserver.V2 vplus/rsskills.V2 vplus/rsconfig.V2 --run rs.main --map-port 1234=0``
in a real child process, real TCP. Malformed lines get error acks and the connection stays usable; a client that
disconnects mid-queue does not disturb the others; a slowloris line holds nobody up; an oversize line is one
-402 and the stream resynchronises; random byte streams get one ack per line."""

from __future__ import annotations

import asyncio
import random
import re
from pathlib import Path

import pytest

from aioadept.protocol import parse_ack
from aioadept.testing.nodes import running_node

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
FILES = [str(VPLUS / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]
ARGS = ("--vplus", *FILES, "--run", "rs.main", "--map-port", "1234=0", "--map-port", "1235=0",
        "--state-endpoint", "none",
        "--time-scale", "20")


class Conn:
    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.r, self.w = reader, writer

    async def ack(self, timeout: float = 10.0):
        return parse_ack((await asyncio.wait_for(self.r.readuntil(b"\n"), timeout)).rstrip(b"\r\n"))

    async def ask(self, line: bytes):
        self.w.write(line + b"\r\n")
        return await self.ack()

    def close(self) -> None:
        self.w.close()


async def connect(port: int) -> Conn:
    return Conn(*await asyncio.open_connection("127.0.0.1", port))


async def with_server(tmp_path, body) -> None:
    async with running_node("sim", *ARGS, log_path=tmp_path / "sim.log") as node:
        await body(int(node.ready["port"]))
    log = (tmp_path / "sim.log").read_text()
    # no task of the server stopped on a V+ error (a console line "<error> (task n)"), only the shutdown's aborts
    assert "Emulator internal error" not in log
    assert not [ln for ln in log.splitlines() if re.search(r"\(task \d+\)$", ln)]


BAD = [
    (b"", None),                                   # empty line: skipped, no ack
    (b"ID:here", -401),                            # ID too short
    (b"abcdefg!:here", -401),                      # bad ID character
    (b"abcdefgh", -401),                           # no skill field
    (b"abcdefgh:", -401),
    (b"abcdefgh:he re", -401),                     # bad skill name
    (b"abcdefgh:nosuchskill", -406),
    (b"abcdefgh:set_speed", -407),
    (b"abcdefgh:set_speed:1:2", -401),            # a fourth field
    (b"abcdefgh:set_speed:abc", -410),
    (b"abcdefgh:set_speed:1e", -410),
    (b"abcdefgh:set_speed:500", -410),
    (b"abcdefgh:move_to:1,2,3", -407),
    (b"abcdefgh:move_to:1000,0,0,0,180,0", -610),
    (b"abcdefgh:move_joints:0,-90,180,0,90,400", -1003),
]


@pytest.mark.timeout(120)
async def test_malformed_lines_get_error_acks_and_the_connection_stays_usable(tmp_path):
    async def body(port: int) -> None:
        c = await connect(port)
        here0 = await c.ask(b"h0000000:here")
        for line, code in BAD:
            if code is None:
                c.w.write(line + b"\r\n")
                continue
            ack = await c.ask(line)
            assert ack.status.value == "error" and ack.error_code == code, (line, ack)
        # oversize: one -402 (with the line's ID), the rest of the line skipped up to its end
        ack = await c.ask(b"big00001:hello:" + b"9" * 300)
        assert (ack.id, ack.error_code) == ("big00001", -402)
        ack = await c.ask(b"h0000001:here")
        assert ack.id == "h0000001" and ack.status.value == "done"
        assert ack.pose == here0.pose                              # nothing above moved the arm
        c.close()
    await with_server(tmp_path, body)


@pytest.mark.timeout(120)
async def test_a_client_gone_mid_queue_and_a_slowloris_line_hold_nobody_up(tmp_path):
    async def body(port: int) -> None:
        other = await connect(port)
        # a client queues a slow motion and more behind it, then disconnects: its queued commands never run
        gone = await connect(port)
        gone.w.write(b"g0000001:set_speed:5\r\ng0000002:move_rel_tool:0,0,50,0,0,0\r\n"
                     b"g0000003:move_rel_tool:0,0,50,0,0,0\r\ng0000004:break\r\n")
        assert (await gone.ack()).id == "g0000001"
        gone.close()
        # a slowloris: one byte of a line at a time
        slow = await connect(port)
        slow.w.write(b"sl")
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        ack = await other.ask(b"o0000001:hello")
        assert ack.id == "o0000001" and loop.time() - t0 < 5.0
        for ch in b"ow0001:here":
            slow.w.write(bytes([ch]))
            await asyncio.sleep(0.01)
        ack = await other.ask(b"o0000002:here")
        assert ack.id == "o0000002"
        slow.w.write(b"\r\n")
        assert (await slow.ack()).id == "slow0001"
        # the gone client's second motion never ran: the arm is at most 50 mm down
        here = await other.ask(b"o0000003:break")
        here = await other.ask(b"o0000004:here")
        first = await other.ask(b"o0000005:here")
        assert first.pose == here.pose
        slow.close()
        other.close()
    await with_server(tmp_path, body)


@pytest.mark.timeout(120)
async def test_random_streams_get_one_ack_per_line(tmp_path):
    rng = random.Random(11)
    alphabet = b"abcdefgh0123456789:,.-+ eE\t!~" + bytes(range(0x80, 0x84))

    async def body(port: int) -> None:
        for rnd in range(5):
            c = await connect(port)
            lines = []
            for i in range(20):
                n = rng.randrange(1, 60)
                junk = bytes(rng.choice(alphabet) for _ in range(n)).replace(b"\r", b"").replace(b"\n", b"")
                lines.append(junk if rng.random() < 0.5 else b"f%02d%05d:" % (rnd, i) + junk)
            # the lines that are not empty after the server's framing get exactly one ack each
            expect = sum(1 for ln in lines if ln)
            data = b"".join(ln + b"\r\n" for ln in lines) + b"z%07d:hello\r\n" % rnd
            # split into random writes
            k = 0
            while k < len(data):
                step = rng.randrange(1, 40)
                c.w.write(data[k:k + step])
                k += step
                await asyncio.sleep(0)
            acks = [await c.ack() for _ in range(expect + 1)]
            assert acks[-1].id == "z%07d" % rnd and acks[-1].status.value == "done"
            assert all(a.status.value in ("error", "done") for a in acks)
            c.close()
    await with_server(tmp_path, body)


MAXQ = 64  # rs.maxq in vplus/rserver.V2: commands one client may have pending


async def _acks_by_id(c: Conn, n: int, timeout: float = 30.0) -> dict[str, object]:
    got: dict = {}
    for _ in range(n):
        ack = await c.ack(timeout)
        assert ack.id not in got, f"two acks for {ack.id}"
        got[ack.id] = ack
    return got


@pytest.mark.timeout(120)
async def test_one_client_cannot_take_the_whole_queue_and_the_reader_never_stops_reading(tmp_path):
    # The V+ server reads every client through one READ: it must never leave data in TCP (a stop would wait
    # behind it). A client with rs.maxq commands pending gets -530 at once for each further line; another
    # client is still admitted, and its stop is served at once.
    async def body(port: int) -> None:
        a, b = await connect(port), await connect(port)
        lines = [b"a0000000:set_speed:5", b"a0000001:move_joints:60,-90,180,0,90,0", b"a0000002:break"]
        lines += [b"q%07d:set_speed:5" % i for i in range(100)]
        a.w.write(b"".join(ln + b"\r\n" for ln in lines))
        collector = asyncio.create_task(_acks_by_id(a, len(lines), timeout=60.0))
        await asyncio.sleep(1.0)  # A's lines are read; its break waits for the 60 deg move at 5 %
        ack = await b.ask(b"b0000001:hello")  # B has nothing pending: answered at once, not refused
        assert (ack.id, ack.status.value) == ("b0000001", "done")
        b.w.write(b"b0000002:set_speed:20\r\nb0000003:stop\r\n")
        got_b = await _acks_by_id(b, 2)
        assert got_b["b0000003"].status.value == "done"
        assert got_b["b0000002"].status.value in ("aborted", "done"), got_b  # queued, not refused
        got = await collector  # every line of A: exactly one ack
        order = [ln[:8].decode() for ln in lines]
        busy = [i for i, cid in enumerate(order) if got[cid].status.value == "error"]
        assert len(busy) >= len(lines) - MAXQ - 2, "more than rs.maxq of A's commands were admitted"
        assert busy == list(range(busy[0], len(lines))), "the refused ones are the last lines, none before"
        assert all(got[order[i]].error_code == -530 and "too many queued" in got[order[i]].error_message
                   for i in busy)
        assert all(got[cid].status.value in ("done", "aborted") for cid in order[:busy[0]])
        a.close()
        b.close()
    await with_server(tmp_path, body)


@pytest.mark.timeout(120)
async def test_a_flood_of_stops_gets_one_done_each_and_nothing_hangs(tmp_path):
    async def body(port: int) -> None:
        c = await connect(port)
        await c.ask(b"f0000000:set_speed:5")
        c.w.write(b"f0000001:move_joints:60,-90,180,0,90,0\r\nf0000002:break\r\n")
        stops = [b"s%07d:stop" % i for i in range(300)]  # beyond the whole command ring
        c.w.write(b"".join(ln + b"\r\n" for ln in stops))
        got = await _acks_by_id(c, 2 + len(stops), timeout=60.0)
        assert all(got[ln[:8].decode()].status.value == "done" for ln in stops)
        assert got["f0000002"].status.value == "aborted"
        c.close()
    await with_server(tmp_path, body)
