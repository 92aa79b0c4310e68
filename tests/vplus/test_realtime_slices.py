"""Fairness in real time: time slices measured on the clock, and READ serving a server LUN's connections in turn.

V+ looks for another task to run at every 1 ms interval, and tasks of equal priority take turns (V+ Language
User's Guide, "Scheduling of Program Execution Tasks", pp. 48-50). The emulator's slice was 2000 loop iterations
of one program frame: a reader busy with one client's flood (each line a few CALLs and short loops) ran 45 ms
at a stretch, and the executor, with a stop's ack, waited that long for each turn (benchmarks/bench_safety.py).
"""

from __future__ import annotations

import asyncio

import pytest

from aioadept.vplus import Emulator, RealClock
from aioadept.vplus.iodev import TcpLun

BUSY = """.PROGRAM busy()
; task 1: 3000 CALLs of a short loop (no back-edge count of its own frame reaches 2000 before the end)
	FOR i = 1 TO 3000
	    CALL work()
	    c1 = c1+1
	END
	done = TRUE
.END
.PROGRAM work()
	AUTO j
	FOR j = 1 TO 60
	    x = j*2
	END
.END
.PROGRAM watch()
; task 2: counts how often task 1 ran between two of its own looks
	WHILE NOT done DO
	    IF c1 <> seen THEN
	        turns = turns+1
	        seen = c1
	    END
	END
.END
"""


async def _serve_until(emu: Emulator, cond, timeout_s: float) -> None:
    stop = asyncio.Event()
    server = asyncio.ensure_future(emu.serve(stop))
    try:
        async with asyncio.timeout(timeout_s):
            while not cond():
                await asyncio.sleep(0.005)
    finally:
        stop.set()
        await server


@pytest.mark.timeout(60)
async def test_busy_tasks_take_turns_every_slice_in_real_time():
    emu = Emulator.from_source(BUSY, filename="t.V2", robot=False, strict=True, clock=RealClock())
    for name in ("c1", "seen", "turns", "done"):
        emu.globals[name] = 0
    emu.execute(1, "busy")
    emu.execute(2, "watch")
    await _serve_until(emu, lambda: emu.globals["done"] != 0, 30)
    # 3000 CALLs of 60 iterations: tens of ms of work, a slice is 1 ms, so the watcher saw task 1 run many times
    # between its looks (with a slice of 2000 iterations of one frame: once or twice in all)
    assert emu.globals["turns"] >= 10, emu.globals["turns"]


def test_virtual_time_keeps_slices_of_loop_iterations():
    """In virtual time nothing changes: a slice is BUDGET iterations of a frame and costs 1 ms."""
    emu = Emulator.from_source(BUSY, filename="t.V2", robot=False, strict=True)
    for name in ("c1", "seen", "turns", "done"):
        emu.globals[name] = 0
    emu.execute(1, "busy")
    emu.execute(2, "watch")
    emu.run(10.0, until=lambda: emu.globals["done"] != 0)
    assert emu.globals["turns"] <= 3


def test_read_serves_the_connections_in_turn_when_one_has_input_released_behind_its_own():
    """A flood's unread input beyond the LUN's buffer is held and released behind its own data; another
    connection's line must still come within a READ or two, not after the flood's whole buffer (16 READs)."""
    emu = Emulator.from_source(".PROGRAM p()\n.END\n", robot=False, strict=True)
    task = emu.execute(1, "p")
    lun = TcpLun(emu.rt, task, 20)
    lun.push(100, 0)
    lun.push(100, 1)
    assert [lun.pop()[:2], lun.pop()[:2]] == [[100, 0], [100, 1]]
    lun.push(1, 0, "f" * 6000)                    # 2048 in the buffer, the rest held
    reads = [lun.pop() for _ in range(8)]        # down to half the buffer: held input released behind it
    assert all(ev[:2] == [1, 0] for ev in reads)
    lun.push(1, 1, "0000abcd:stop\r\n")
    n = 0
    while n < 3:                                  # the stop's line within the next two reads
        n += 1
        ev = lun.pop()
        if ev[1] == 1:
            break
    assert ev == [1, 1, "0000abcd:stop\r\n"] and n <= 2, (n, ev[:2])
    # the flood's input is all there, in order, after it
    rest = "".join(ev[2] for ev in iter(lun.pop, None) if ev[0] == 1)
    assert len(rest) + 8 * 128 + (n - 1) * 128 == 6000 and set(rest) == {"f"}


def test_a_reset_connection_s_unread_input_is_dropped_and_its_close_comes_at_once():
    """A reset connection's input not yet read goes with it (a TCP stack drops a reset connection's receive
    queue): its 101 is the next READ, not after a flood's held 256 KiB, which kept its slot for seconds."""
    emu = Emulator.from_source(".PROGRAM p()\n.END\n", robot=False, strict=True)
    task = emu.execute(1, "p")
    lun = TcpLun(emu.rt, task, 20)
    lun.push(100, 0)
    lun.push(100, 1)
    assert [lun.pop()[:2], lun.pop()[:2]] == [[100, 0], [100, 1]]
    lun.push(1, 0, "f" * 100_000)
    lun.push(1, 1, "0000abcd:here\r\n")
    lun.reserved.add(0)
    lun.drop_input(0)
    lun.push(101, 0)
    assert lun.pop() == [1, 1, "0000abcd:here\r\n"]
    assert lun.pop()[:2] == [101, 0]
    assert lun.pop() is None and lun.buffered == 0 and 0 not in lun.reserved
