"""Safety promises of the simulated controller over real TCP on 127.0.0.1 (docs/security.md).

Raw sockets, so what is checked is the server, not a client's politeness:

- a client that dies with a second motion queued: that motion never runs (item 1);
- with --max-clients reached by idle peers, a newcomer's ``stop`` is executed at once (item 2);
- a ``stop`` is read and acted on while three clients flood cheap commands (item 2; the p95 is in
  benchmarks/bench_safety.py, here only a generous bound);
- three stops in a row all get ``done`` (item 2);
- bad values answer error acks and the connection stays usable (item 6);
- ``here`` from idle connections is answered while another client's arm moves (item 9);
- forward processing is one motion deep.
"""

from __future__ import annotations

import asyncio
import contextlib

import pytest

from aioadept.protocol import NO_ID, ErrorCode, LineFramer, Status, parse_ack
from aioadept.testing.sim import running_sim


class Raw:
    """A raw protocol connection: write lines, read acks by ID."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer
        self.framer = LineFramer(1024)
        self.acks: list = []

    @classmethod
    async def open(cls, sim) -> Raw:
        return cls(*await asyncio.open_connection(sim.host, sim.port))

    def send(self, *lines: bytes) -> None:
        self.writer.write(b"".join(line + b"\r\n" for line in lines))

    async def ack(self, mid: str, timeout: float = 10.0):
        """The next ack with this ID (reading on until it comes)."""
        async with asyncio.timeout(timeout):
            while True:
                for i, a in enumerate(self.acks):
                    if a.id == mid:
                        return self.acks.pop(i)
                chunk = await self.reader.read(65536)
                if not chunk:
                    raise EOFError(f"closed before the ack of {mid}; got {self.acks}")
                self.acks += [parse_ack(line) for line in self.framer.feed(chunk)]

    async def closed(self, timeout: float = 10.0) -> list:
        """Every ack until the server closes."""
        async with asyncio.timeout(timeout):
            while True:
                try:
                    chunk = await self.reader.read(65536)
                except ConnectionResetError:
                    return self.acks
                if not chunk:
                    return self.acks
                self.acks += [parse_ack(line) for line in self.framer.feed(chunk)]

    async def close(self) -> None:
        self.writer.close()
        with contextlib.suppress(OSError):
            await self.writer.wait_closed()


async def wait_until(pred, timeout: float = 10.0) -> None:
    async with asyncio.timeout(timeout):
        while not pred():
            await asyncio.sleep(0.005)


# -- item 1 ----------------------------------------------------------------------------------------------------

@pytest.mark.timeout(30)
async def test_a_client_that_dies_with_a_second_motion_queued_never_gets_it_run():
    async with running_sim(time_scale=4) as sim:
        c = await Raw.open(sim)
        # A long move (J1 0 -> 150 deg: ~0.7 s robot time / 4), then a second one back, then close at once.
        c.send(b"0000a001:move_joints:150,-90,180,0,90,0", b"0000a002:move_joints:-150,-90,180,0,90,0")
        await c.ack("0000a001")
        await c.close()
        await wait_until(lambda: not sim.controller.connections)
        # Wait past the time the whole first motion takes: the arm ends at 150, the second move never ran.
        await wait_until(lambda: not sim.controller.trajectory.in_motion(sim.now()))
        assert sim.controller.joints_at(sim.now())[0] == pytest.approx(150.0, abs=1e-6)
        assert sim.controller.queued() == 0 and not sim.controller.busy


# -- item 2: the reserved stop path ------------------------------------------------------------------------------

@pytest.mark.timeout(30)
async def test_with_max_clients_taken_by_idle_peers_a_newcomers_stop_is_executed():
    async with running_sim(time_scale=1, max_clients=2, stop_window_s=1.0) as sim:
        mover = await Raw.open(sim)
        idle = await Raw.open(sim)  # a hung peer: connected, says nothing
        mover.send(b"0000b001:move_joints:150,-90,180,0,90,0", b"0000b002:break")
        await mover.ack("0000b001")
        await wait_until(lambda: len(sim.controller.connections) == 2)
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        s = await Raw.open(sim)  # over the limit
        s.send(b"0000c001:stop")
        await wait_until(lambda: sim.controller.trajectory.t_rest_s < sim.now() + 0.5, timeout=1.0)
        acted = loop.time() - t0  # the stop was executed: the arm is decelerating (rest within 0.5 s)
        stop = await s.ack("0000c001")
        assert stop.status is Status.DONE
        assert (await mover.ack("0000b002")).status is Status.ABORTED
        assert acted < 1.0  # generous: the 100 ms promise is measured in benchmarks/bench_safety.py
        assert not sim.controller.trajectory.in_motion(sim.now())
        # The stop-only connection then closes without a refusal; anything but stop is still refused.
        assert await s.closed() == []
        other = await Raw.open(sim)
        other.send(b"0000c002:move_joints:0,-90,180,0,90,0")
        acks = await other.closed()
        assert [(a.id, a.error_code) for a in acks] == [(NO_ID, ErrorCode.SERVER_BUSY)]
        assert "only stop" in acks[0].error_message
        await wait_until(lambda: len(sim.controller.connections) == 2)
        assert sim.controller.joints_at(sim.now())[0] < 150 and not sim.controller.trajectory.in_motion(sim.now())
        for c in (mover, idle, s, other):
            await c.close()


@pytest.mark.timeout(30)
async def test_the_stop_path_cannot_be_filled_by_silent_newcomers():
    async with running_sim(instant=True, max_clients=1, stop_window_s=5.0, max_stop_probes=3) as sim:
        first = await Raw.open(sim)
        silent = [await Raw.open(sim) for _ in range(5)]  # more than max_stop_probes, all silent
        s = await Raw.open(sim)
        s.send(b"0000d001:stop")
        assert (await s.ack("0000d001")).status is Status.DONE
        for c in (first, *silent, s):
            await c.close()


# -- item 2: stop under a flood ------------------------------------------------------------------------------------

@pytest.mark.timeout(60)
async def test_a_stop_is_acted_on_while_three_clients_flood_cheap_commands():
    async with running_sim(time_scale=1) as sim:
        mover, stopper = await Raw.open(sim), await Raw.open(sim)
        flooders = [await Raw.open(sim) for _ in range(3)]
        stop_flood = asyncio.Event()

        async def flood(c: Raw, k: int) -> None:
            batch = b"".join(b"%07x%d:here\r\n" % (i, k) for i in range(200))

            async def discard() -> None:
                with contextlib.suppress(OSError):
                    while await c.reader.read(65536):
                        pass

            reading = asyncio.create_task(discard())
            with contextlib.suppress(OSError):
                while not stop_flood.is_set():
                    c.writer.write(batch)
                    await c.writer.drain()
            reading.cancel()

        tasks = [asyncio.create_task(flood(c, k)) for k, c in enumerate(flooders)]
        loop = asyncio.get_running_loop()
        latencies = []
        try:
            for i in range(5):
                target = 150 if i % 2 == 0 else -150
                mover.send(b"0000e%03d:move_joints:%d,-90,180,0,90,0" % (2 * i, target),
                           b"0000e%03d:break" % (2 * i + 1))
                await mover.ack("0000e%03d" % (2 * i), timeout=20)
                t0 = loop.time()
                stopper.send(b"0000s%03d:stop" % i)
                brk = await mover.ack("0000e%03d" % (2 * i + 1), timeout=20)
                latencies.append(loop.time() - t0)
                assert brk.status is Status.ABORTED, (i, brk)  # the stop was acted on before the move ended
                assert (await stopper.ack("0000s%03d" % i, timeout=20)).status is Status.DONE
        finally:
            stop_flood.set()
            await asyncio.gather(*tasks, return_exceptions=True)
        # Generous, so it is not flaky on a loaded machine: the p95 <= 100 ms promise is measured by
        # benchmarks/bench_safety.py (before the fix: p95 0.8 s, max 3.3 s, some stops after the motion ended).
        assert max(latencies) < 1.0, latencies
        for c in (mover, stopper, *flooders):
            await c.close()


@pytest.mark.timeout(30)
async def test_three_stops_in_a_row_each_get_done():
    async with running_sim(time_scale=1) as sim:
        c = await Raw.open(sim)
        c.send(b"0000f001:move_joints:150,-90,180,0,90,0", b"0000f002:break")
        await c.ack("0000f001")
        c.send(b"0000f003:stop", b"0000f004:stop", b"0000f005:stop")
        acks = [await c.ack(m) for m in ("0000f003", "0000f004", "0000f005")]
        assert [a.status for a in acks] == [Status.DONE] * 3
        assert (await c.ack("0000f002")).status is Status.ABORTED
        assert len({a.pose for a in acks}) == 1  # all at the same rest pose
        await c.close()


# -- item 6 -------------------------------------------------------------------------------------------------------

@pytest.mark.timeout(30)
async def test_bad_values_answer_error_acks_and_the_connection_stays_usable():
    bad = [
        (b"0000g001:set_speed:0.001", "0000g001", ErrorCode.ILLEGAL_VALUE),
        (b"0000g002:set_speed:0." + b"0" * 20 + b"1", "0000g002", ErrorCode.ILLEGAL_VALUE),
        (b"0000g003:set_speed:1e308", "0000g003", ErrorCode.ILLEGAL_VALUE),
        (b"0000g004:set_speed:1_0", "0000g004", ErrorCode.ILLEGAL_VALUE),
        (b"0000g005:set_speed:inf", "0000g005", ErrorCode.ILLEGAL_VALUE),
        (b"0000g006:set_speed:\t10", "0000g006", ErrorCode.ILLEGAL_VALUE),
        (b"0000g007:set_speed:1\x070", "0000g007", ErrorCode.ILLEGAL_VALUE),
        (b"0000g008:move_to:480,0,500,0,180,100000000000000000000", "0000g008", ErrorCode.ILLEGAL_VALUE),
        (b"0000g009:move_rel_world:0,0,0,0,0,720", "0000g009", ErrorCode.ILLEGAL_VALUE),
        (b"00000000:move_joints:30,-90,180,0,90,0", NO_ID, ErrorCode.MALFORMED_MESSAGE),
    ]
    async with running_sim(instant=True) as sim:
        c = await Raw.open(sim)
        home = sim.controller.joints_deg
        for k, (line, mid, code) in enumerate(bad):
            c.send(line)
            ack = await c.ack(mid)
            assert (ack.status, ack.error_code) == (Status.ERROR, code), line
            c.send(b"0000h%03d:here" % k)
            assert (await c.ack("0000h%03d" % k)).status is Status.DONE  # still usable
        assert sim.controller.joints_deg == home
        await c.close()


@pytest.mark.timeout(30)
async def test_a_duplicate_pending_id_answers_an_error_and_nothing_hangs():
    async with running_sim(time_scale=2) as sim:
        c = await Raw.open(sim)
        c.send(b"0000i001:move_joints:60,-90,180,0,90,0", b"0000i002:break",
               b"0000i002:move_joints:-60,-90,180,0,90,0")
        first = await c.ack("0000i001")
        dup = await c.ack("0000i002")  # the duplicate's refusal comes at once, before the break's done
        assert first.status is Status.DONE
        assert dup.status is Status.ERROR and dup.error_code == ErrorCode.MALFORMED_MESSAGE
        assert (await c.ack("0000i002")).status is Status.DONE  # the break itself
        assert sim.controller.joints_at(sim.now())[0] == pytest.approx(60.0)
        await c.close()


# -- item 9 -------------------------------------------------------------------------------------------------------

@pytest.mark.timeout(60)
async def test_here_from_50_idle_clients_is_answered_while_another_arm_moves():
    async with running_sim(time_scale=1, max_clients=64) as sim:
        mover = await Raw.open(sim)
        pollers = [await Raw.open(sim) for _ in range(50)]
        mover.send(b"0000j001:move_joints:150,-90,180,0,90,0", b"0000j002:break")
        await mover.ack("0000j001")
        t_rest = sim.controller.trajectory.t_rest_s
        for k, p in enumerate(pollers):
            p.send(b"0000k%03d:here" % k)
        acks = [await p.ack("0000k%03d" % k) for k, p in enumerate(pollers)]
        # Each answered mid-motion, long before the mover's break completes.
        assert all(a.status is Status.DONE for a in acks)
        assert max(a.t_done_s for a in acks) < t_rest - 0.2
        assert sim.controller.trajectory.in_motion(max(a.t_done_s for a in acks))
        assert (await mover.ack("0000j002")).status is Status.DONE
        for c in (mover, *pollers):
            await c.close()


# -- forward processing is one motion deep ----------------------------------------------------------------------------------------------

@pytest.mark.timeout(30)
async def test_forward_processing_is_one_motion_deep_over_tcp():
    async with running_sim(time_scale=2) as sim:
        c = await Raw.open(sim)
        c.send(b"0000l001:move_joints:60,-90,180,0,90,0", b"0000l002:move_joints:0,-90,180,0,90,0",
               b"0000l003:break")
        a = await c.ack("0000l001")
        b = await c.ack("0000l002")
        brk = await c.ack("0000l003")
        # b acks as a nearly completes (a takes ~0.34 s / 2), not at once; the break when b has completed.
        assert b.t_done_s - a.t_done_s > 0.1
        assert brk.t_done_s - b.t_done_s > 0.1
        await c.close()
