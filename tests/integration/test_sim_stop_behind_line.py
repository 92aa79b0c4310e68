"""A ``stop`` sent right behind a long straight line (``move_to_s``) is served at once: the line's planning no
longer holds the sim server's event loop while the stop waits.

``aioadept sim`` as a real subprocess, raw TCP on 127.0.0.1: the arm rests at A; a 1000 mm MOVES (1002 samples)
goes to the main port and, the moment it is written, a stop to the stop port.

Measured on the 2-core test machine before the array planner (main at 68c909c, 8 rounds): the server solved the
line's 1002 samples one inverse kinematics at a time, 33-46 ms, before it read the stop; the stop was acked 62-80 ms
after it was sent (median 69 ms), the arm having moved 13-23 mm along the line by then; the in-process server's
event loop stalled up to 54 ms. With it: 6-16 ms and 0.1-0.9 mm (planning 1.5-3 ms, stall under 5 ms); with two
busy loops hogging both cores, 3-41 ms and 0.1-3.2 mm against 103-224 ms of old planning.

The assertions compare with the old planner timed in this process on the same line (``batch=False``), not with
fixed times, and take the best of three rounds, so a loaded machine slows both sides alike.
"""

from __future__ import annotations

import asyncio
import math
import time

import pytest

from aioadept.geometry import Pose
from aioadept.protocol import LineFramer, Status, parse_ack
from aioadept.robots import viper_s850 as kin
from aioadept.sim.line import plan_tool_line
from aioadept.testing.nodes import running_node

A = (350.0, -500.0, 300.0, 0.0, 180.0, 0.0)
B = (350.0, 500.0, 300.0, 0.0, 180.0, 90.0)


class Peer:
    """One raw connection: write lines, wait for the ack of an ID (keeping others that arrive first)."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer
        self.framer = LineFramer(max_line=1024)
        self.acks = []

    @classmethod
    async def open(cls, host: str, port: int) -> Peer:
        return cls(*await asyncio.open_connection(host, port))

    def send(self, line: str) -> None:
        self.writer.write(line.encode() + b"\r\n")

    async def ack(self, id_: str):
        while True:
            for i, a in enumerate(self.acks):
                if a.id == id_:
                    return self.acks.pop(i)
            chunk = await self.reader.read(4096)
            assert chunk, "the server closed the connection"
            self.acks += [parse_ack(line) for line in self.framer.feed(chunk)]

    async def close(self) -> None:
        self.writer.close()
        await self.writer.wait_closed()


def old_planning_s() -> float:
    """The line planned one scalar inverse kinematics per sample (the planner before), best of three (s)."""
    start = kin.inverse(Pose(*A), kin.HOME_JOINTS_DEG)
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        path = plan_tool_line(start, Pose(*B), batch=False)
        best = min(best, time.perf_counter() - t0)
    assert len(path.s) > 1000
    return best


@pytest.mark.timeout(60)
async def test_a_stop_right_behind_a_long_moves_is_served_before_the_line_could_have_been_planned():
    reference_s = old_planning_s()
    async with running_node("sim", "--port", "0", "--state-endpoint", "none", expect_clean_exit=False) as sim:
        host, port, stop_port = sim.ready["host"], int(sim.ready["port"]), int(sim.ready["stop_port"])
        main = await Peer.open(host, port)
        latencies, travels = [], []
        for r in range(3):
            main.send(f"{r:04x}0001:move_to:{','.join(map(str, A))}")
            main.send(f"{r:04x}0002:break")
            await main.ack(f"{r:04x}0002")
            stop = await Peer.open(host, stop_port)
            main.send(f"{r:04x}0003:move_to_s:{','.join(map(str, B))}")
            stop.send(f"{r:04x}0004:stop")
            t_sent = time.perf_counter()
            stopped = await stop.ack(f"{r:04x}0004")
            latencies.append(time.perf_counter() - t_sent)
            assert stopped.status is Status.DONE
            moves = await main.ack(f"{r:04x}0003")
            assert moves.status in (Status.DONE, Status.ABORTED), moves  # started (then stopped), or never started
            # Where the arm came to rest: how far it went along the line before the stop acted.
            travels.append(math.dist((stopped.pose.x, stopped.pose.y, stopped.pose.z), A[:3]))
            await stop.close()
        await main.close()
    # Before: the stop waited for the whole planning (its ack came later than the old planner takes), and the arm
    # was 13-23 mm down the line by then.
    assert min(latencies) < reference_s / 2, (latencies, reference_s)
    assert min(travels) < 5.0, travels  # 0.1-0.9 mm (2 mm with both cores busy elsewhere)
