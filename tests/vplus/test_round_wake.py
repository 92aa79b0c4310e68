"""A task woken by an earlier task in the same scheduler round runs in its turn of that round.

The emulated rserver's reader sleeps in WAIT.EVENT until the executor (task 1) queues an ack and sets its event;
running the reader in the same round, not one round later, is one round less between a command and its ack.
"""

from __future__ import annotations

from aioadept.vplus import Emulator

SRC = """.PROGRAM waiter()
    WAIT.EVENT 1, 10
    got = 1
.END

.PROGRAM setter()
    WAIT go
    SET.EVENT 2
.END
"""


def test_task_woken_earlier_in_a_round_runs_in_that_round() -> None:
    emu = Emulator.from_source(SRC, robot=False, strict=True)
    emu.globals["go"] = 0
    emu.globals["got"] = 0
    emu.execute(2, "waiter")
    emu.execute(1, "setter")
    rt = emu.rt
    rt.run_round()                        # both block: setter in WAIT go, waiter in WAIT.EVENT
    assert emu.globals["got"] == 0
    emu.globals["go"] = 1
    rt.wake_conditions()
    rt.run_round()                        # setter sets task 2's event; task 2 comes later in the same round
    assert emu.globals["got"] == 1


def test_a_task_still_runs_once_per_round() -> None:
    src = """.PROGRAM spin()
    FOR i = 1 TO 3
        n = n+1
        WAIT
    END
.END
"""
    emu = Emulator.from_source(src, robot=False, strict=True)
    emu.globals["n"] = 0
    emu.execute(1, "spin")
    emu.rt.run_round()
    assert emu.globals["n"] == 1
