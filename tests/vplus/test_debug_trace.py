"""The emulator's line hooks (aioadept.vplus.trace): the instrumented form calls the tracer at each V+ line and
error with the V+ call stack; a held task waits while the others run on."""

from __future__ import annotations

from aioadept.vplus import Emulator

SRC = """.PROGRAM main()
    AUTO a
    a = 1
    CALL sub(a)
    TYPE "done ", a
.END
.PROGRAM sub(x)
    x = x + 1
    y = 1/0
.END
.PROGRAM other()
    n = 0
    WHILE n < 50 DO
        n = n + 1
        WAIT
    END
.END
"""


class Recorder:
    def __init__(self) -> None:
        self.seen: list = []
        self.hold_at: tuple[str, int] | None = None

    def line(self, task, frame) -> None:
        self.seen.append((task.num, frame.program, frame.line))
        if (frame.program, frame.line) == self.hold_at:
            task.held = True

    def error(self, task, err, frames) -> None:
        self.seen.append(("error", err.code, [(f.program, f.file, f.line) for f in frames]))


def test_every_line_and_the_error_with_its_stack_reach_the_tracer():
    emu = Emulator.from_source(SRC, robot=False)
    rec = Recorder()
    emu.set_tracer(rec, all_lines=True)
    emu.execute(0, "main")
    emu.run(1.0)
    assert rec.seen == [(0, "main", 3), (0, "main", 4), (0, "sub", 8), (0, "sub", 9),
                        ("error", -412, [("sub", "<source>", 9), ("main", "<source>", 4)])]


def test_a_held_task_waits_with_its_stack_readable_while_another_task_runs_on():
    emu = Emulator.from_source(SRC, robot=False)
    rec = Recorder()
    rec.hold_at = ("sub", 9)
    emu.set_tracer(rec)
    emu.rt.trace_lines("sub").add(9)          # a breakpoint: only this line calls the tracer
    emu.execute(0, "main")
    emu.execute(1, "other")
    emu.run(2.0)
    T = emu.task(0)
    assert T.held and T.state == "running"
    assert rec.seen == [(0, "sub", 9)]
    assert emu.globals["n"] == 50.0            # task 1 ran to its end meanwhile
    inner, outer = T.frames
    assert (inner.program, inner.line, outer.program, outer.line) == ("sub", 9, "main", 4)
    assert inner.args()[0][:2] == ("x", 2.0) and outer.autos["a"] == 2.0
    inner.args()[0][2][0][inner.args()[0][2][1]] = 41.0      # set the argument: main's a, by reference
    emu.rt.trace_lines("sub").clear()
    emu.rt.release(T)
    emu.run(1.0)
    assert T.state == "error" and T.error.code == -412
    assert outer.autos["a"] == 41.0
