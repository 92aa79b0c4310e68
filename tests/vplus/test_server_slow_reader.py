"""The shipped V+ server stays safe when its reader is slow right after a BRAKE, as a real controller's task 2 may
be (it is time-sliced at any instruction, and the instrumented form of the emulator is slower).

The reader brakes the arm when it reads a stop (``rs.stop``) and when a client goes during its motion skill
(``rs.slotgone``); that BRAKE ends the executor's wait (a skill's BREAK, a MOVE waiting for its turn). If the
reader marks the stop (``rs.stopin``) or the client's new generation (``rs.cgen``) only after the BRAKE, task 1
can run in between and see neither: a hand skill switched the valves, an output queued behind a motion switched,
a waiting break was acked ``done``, the next move of a client that had gone ran. Here a tracer (the emulator's
API, :mod:`aioadept.vplus.trace`) holds the reader at the statement after each of its BRAKEs for ``HOLD_S``,
which makes that interleaving certain; the server must mark first and brake after (docs/vplus.md, "stop").
In-process emulator, real TCP on 127.0.0.1.
"""

from __future__ import annotations

import asyncio
import contextlib
from pathlib import Path

import pytest

from aioadept.ports import free_port
from aioadept.protocol import Status, parse_ack
from aioadept.sim.controller import Controller
from aioadept.sim.io import HAND_TIME_S
from aioadept.vplus import Emulator, RealClock
from aioadept.vplus import nodes as N
from aioadept.vplus.emulator import make_robot
from aioadept.vplus.iodev import Network

ROOT = Path(__file__).resolve().parents[2] / "vplus"
SERVER = [ROOT / f for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]
HOLD_S = 0.3                 # the reader's pause after a BRAKE: far longer than the arm takes to rest (~30 ms)
SLOW = ("set_speed:10", "move_joints:150,-90,180,0,90,0")     # about 6 s


class HoldAfterBrake:
    """Holds a task for ``HOLD_S`` at the first statement it runs after a BRAKE of ``programs`` (whichever
    program that statement is in): its line hook at the BRAKE steps the task, the next one holds it."""

    def __init__(self, emu: Emulator, programs: tuple[str, ...]) -> None:
        self.rt = emu.rt
        self.held: list[tuple[str, str]] = []         # (program of the BRAKE, program of the hold)
        self.braked: dict[int, str] = {}              # task number -> program of its last BRAKE
        for name in programs:
            brakes = {line for line, st in emu.rt.module.programs[name].steps
                      if isinstance(st, N.Word) and st.word == "BRAKE"}
            assert brakes, f"{name} has no BRAKE"
            self.rt.trace_lines(name).update(brakes)

    def line(self, task, frame) -> None:
        if not task.trace:                            # at a BRAKE: hold at the next statement
            task.trace = True
            self.braked[task.num] = frame.program
            return
        task.trace = False
        self.held.append((self.braked[task.num], frame.program))
        task.held = True
        asyncio.get_running_loop().call_later(HOLD_S, self.rt.release, task)

    def error(self, task, err, frames) -> None:
        pass


class Conn:
    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer

    async def send(self, *lines: str) -> None:
        self.writer.write(b"".join(ln.encode() + b"\r\n" for ln in lines))
        await self.writer.drain()

    async def acks(self, n: int, timeout: float = 15.0):
        async with asyncio.timeout(timeout):
            return [parse_ack((await self.reader.readuntil(b"\r\n"))[:-2]) for _ in range(n)]

    async def close(self) -> None:
        self.writer.close()
        with contextlib.suppress(OSError):
            await self.writer.wait_closed()


@contextlib.asynccontextmanager
async def slow_reader_server():
    emu = Emulator.load(*SERVER, strict=True, clock=RealClock(), robot=make_robot(Controller()))
    port = free_port()
    emu.rt.devices = Network("127.0.0.1", {1234: port, 1235: free_port()})
    tracer = HoldAfterBrake(emu, ("rs.stop", "rs.slotgone"))
    emu.set_tracer(tracer)
    stop = asyncio.Event()
    emu.execute(0, "rs.main")
    serving = asyncio.create_task(emu.serve(stop))
    try:
        async with asyncio.timeout(20):
            while not any("READY stop port" in line for line in emu.console):
                await asyncio.sleep(0.02)

        async def connect() -> Conn:
            return Conn(*await asyncio.open_connection("127.0.0.1", port))

        yield emu, tracer, connect
    finally:
        stop.set()
        await serving


async def _pose(c: Conn, ident: str):
    await c.send(f"{ident}:here")
    (ack,) = await c.acks(1)
    return ack.pose


@pytest.mark.timeout(60)
async def test_a_reader_slow_after_its_brake_lets_nothing_act_behind_a_stop_or_a_client_gone():
    async with slow_reader_server() as (emu, tracer, connect):
        c, s = await connect(), await connect()
        # A hand skill waiting (its BREAK) for a slow motion when a stop comes: aborted, the valves never switch.
        await c.send(f"a0000001:{SLOW[0]}", f"a0000002:{SLOW[1]}", "a0000003:close_hand")
        assert all(a.ok for a in await c.acks(2))
        await asyncio.sleep(0.3)
        await s.send("a0000004:stop")
        (hand,) = await c.acks(1, timeout=30)
        (stop,) = await s.acks(1, timeout=30)
        assert (hand.id, hand.status, stop.status) == ("a0000003", Status.ABORTED, Status.DONE), (hand, stop)
        await asyncio.sleep(6 * HAND_TIME_S)
        assert not emu.signals.get(1) and not emu.signals.get(2), "close_hand switched the valves after the stop"
        # A break waiting for the motion, then an output behind a second motion waiting for its turn: all aborted.
        await c.send(f"b0000001:{SLOW[1]}", "b0000002:break", "b0000003:move_joints:0,-90,180,0,90,0",
                     "b0000004:signal:5")
        assert (await c.acks(1))[0].ok
        await asyncio.sleep(0.3)
        await s.send("b0000005:stop")
        acks = await c.acks(3, timeout=30)
        assert [(a.id, a.status) for a in acks] == [("b0000002", Status.ABORTED), ("b0000003", Status.ABORTED),
                                                    ("b0000004", Status.ABORTED)], acks
        assert (await s.acks(1, timeout=30))[0].status is Status.DONE
        assert not emu.signals.get(5), "signal:5 switched after the stop"
        # A client that goes while its move waits for its turn: its next move never runs.
        g = await connect()
        await g.send(f"c0000001:{SLOW[0]}", f"c0000002:{SLOW[1]}", "c0000003:move_joints:0,-90,180,0,90,0",
                     "c0000004:move_joints:-150,-90,180,0,90,0")
        assert all(a.ok for a in await g.acks(2))
        await asyncio.sleep(0.3)
        await g.close()
        await asyncio.sleep(2 * HOLD_S)
        rest = await _pose(s, "c0000005")
        await asyncio.sleep(0.5)
        assert await _pose(s, "c0000006") == rest, "a move of a client that had gone ran"
        assert {p for p, _ in tracer.held} == {"rs.stop", "rs.slotgone"}, tracer.held
        await c.close()
        await s.close()
