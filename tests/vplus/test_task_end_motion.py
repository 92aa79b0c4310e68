"""What a task's end does to the motion it started (virtual time, no sockets): a task stopped by an error, HALT or
ABORT brakes its robot (no motion goes on that no program commands; docs/vplus.md, "When a task stops"); a
program that runs to its end leaves its last motion to complete, as before."""

from __future__ import annotations

import pytest

from aioadept.vplus import Emulator

SRC = """
.PROGRAM moving.err()
	SPEED 10
	MOVE #PPOINT(60, -90, 180, 0, 90, 0)
	x = 1/0
.END

.PROGRAM moving.halt()
	SPEED 10
	MOVE #PPOINT(60, -90, 180, 0, 90, 0)
	HALT
.END

.PROGRAM moving.abort()
	SPEED 10
	MOVE #PPOINT(60, -90, 180, 0, 90, 0)
	ABORT 0
.END

.PROGRAM moving.ends()
	SPEED 10
	MOVE #PPOINT(60, -90, 180, 0, 90, 0)
.END
"""


def ended(program: str) -> tuple[Emulator, object]:
    emu = Emulator.from_source(SRC, strict=True)
    seen = []
    emu.rt.on_task_end = seen.append
    T = emu.execute(0, program)
    emu.run(0.2)                      # the MOVE starts at once (forward processing), then the task ends
    assert seen == [T], "on_task_end is called once, with the task"
    return emu, T


@pytest.mark.parametrize(("program", "state"), [("moving.err", "error"), ("moving.halt", "done"),
                                                ("moving.abort", "done")])
def test_a_task_stopped_by_an_error_halt_or_abort_brakes_its_motion(program, state):
    emu, T = ended(program)
    traj = emu.controller.trajectory
    assert T.state == state
    assert traj.end_deg[0] < 10.0, traj.end_deg       # stopped near where it was, not at 60
    assert not traj.in_motion(emu.time_s)
    assert emu.robot.owner is None                    # and the robot was released


def test_halt_says_where_it_stopped():
    _, T = ended("moving.halt")
    assert T.halted_at == ("<source>", "moving.halt", 11)     # the line of HALT in the source text


def test_a_program_that_runs_to_its_end_leaves_its_motion_to_complete():
    emu, T = ended("moving.ends")
    traj = emu.controller.trajectory
    assert T.state == "done"
    assert traj.end_deg[0] == pytest.approx(60.0)
    assert traj.in_motion(emu.time_s)
