"""TCP input for a task that waits for it wakes that task; the other tasks' WAIT conditions are re-tested after its
turn, when they can see what it did with the input, not once before it as well.

The emulated rserver's executor (task 1) waits in ``WAIT cond`` for the reader (task 2) to queue a command: a
re-test at the input's arrival came before the reader's turn, found nothing, and was a task resumption spent on
every command (docs/vplus.md, Performance, seventh round).
"""

from __future__ import annotations

from aioadept.vplus import Emulator

SRC = """.PROGRAM watcher()
    WAIT go
    seen = n
.END

.PROGRAM reader()
    WAIT.EVENT 1, 10
    n = n+1
    go = TRUE
.END

.PROGRAM idle()
    WAIT.EVENT 1, 10
.END
"""


def _blocked(*tasks: tuple[int, str]) -> Emulator:
    emu = Emulator.from_source(SRC, robot=False, strict=True)
    emu.globals["go"] = 0
    emu.globals["n"] = 0
    for num, prog in tasks:
        emu.execute(num, prog)
    while emu.rt.any_ready():             # all block: watcher in WAIT go, the others in WAIT.EVENT
        emu.rt.run_round()
    return emu


def test_input_wakes_its_reader_and_the_condition_is_retested_after_it() -> None:
    emu = _blocked((1, "watcher"), (2, "reader"))
    rt, watcher = emu.rt, emu.task(1)
    assert watcher.cond_wait
    rt.io_event(emu.task(2))              # data on one of task 2's TCP LUNs (iodev.TcpLun.push)
    assert emu.task(2).wake <= rt.now
    assert watcher.wake > rt.now          # not resumed before the reader: nothing has changed yet
    rt.run_round()                        # the reader takes the input and sets go
    assert emu.globals["go"] != 0 and "seen" not in emu.globals
    rt.run_round()                        # the condition is re-tested in the next round, no cycle later
    assert emu.globals["seen"] == 1
    assert rt.now == 0.0


def test_input_nobody_waits_for_retests_conditions_at_once() -> None:
    # the I/O's task is not in READ or WAIT.EVENT: nothing else will run for it, so the conditions are re-tested
    # at once (a WAIT condition may read the input itself, e.g. with GETC)
    emu = _blocked((1, "watcher"), (2, "idle"))
    rt, watcher = emu.rt, emu.task(1)
    emu.task(2).event_wait = False
    rt.io_event(emu.task(2))
    assert watcher.wake <= rt.now
