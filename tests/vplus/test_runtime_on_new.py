"""``Runtime.on_new``: a tool (V+ line coverage) attaches a tracer to every runtime a process makes, before any of
its tasks starts, without wrapping ``Runtime.__init__``."""

from __future__ import annotations

from aioadept.vplus import Emulator
from aioadept.vplus.runtime import Runtime

SOURCE = """.PROGRAM count()
\tAUTO i
\tx = 0
\tFOR i = 1 TO 3
\t    x = x+i
\tEND
.END
"""


class Lines:
    def __init__(self) -> None:
        self.ran: list[tuple[str, int]] = []

    def line(self, task, frame) -> None:
        self.ran.append((frame.program, frame.line))

    def error(self, task, err, frames) -> None:
        pass


def test_a_hook_of_on_new_traces_every_runtime_made_after_it():
    seen: list[Runtime] = []
    tracer = Lines()

    def attach(rt: Runtime) -> None:
        assert rt.programs and not rt.active()        # compiled, no task started
        seen.append(rt)
        rt.set_tracer(tracer, all_lines=True)

    Runtime.on_new.append(attach)
    try:
        first, second = Emulator.from_source(SOURCE), Emulator.from_source(SOURCE)
    finally:
        Runtime.on_new.remove(attach)
    assert seen == [first.rt, second.rt]
    first.call("count")
    assert first.globals["x"] == 6
    assert tracer.ran == [("count", 3), ("count", 4)] + [("count", 5)] * 3
    assert Emulator.from_source(SOURCE).rt.tracer is None     # removed: later runtimes run untraced
