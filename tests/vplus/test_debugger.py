"""The debugger's core (aioadept.vplus.debugger) on the emulator in virtual time: breakpoints (conditions, hit
counts, logpoints), stepping, exception stops, inspection, evaluate and set; one stopped task stops no other."""

from __future__ import annotations

import pytest

from aioadept.vplus import Emulator
from aioadept.vplus.debugger import DebugError, Debugger, children, render

SRC = """.PROGRAM main()
    AUTO a, $s
    LOCAL k
    a = 1
    $s = "abc"
    SET spot = TRANS(10, 20, 30, 0, 90, 0)
    FOR k = 1 TO 5
        CALL add(a, k)
    END
    TYPE "a=", a
.END
.PROGRAM add(x, y)
    AUTO t
    t = x + y
    x = t
.END
.PROGRAM bad()
    z = 1/0
    TYPE "after"
.END
.PROGRAM trapped()
    REACTE handler
    z = 1/0
    TYPE "went on"
.END
.PROGRAM handler()
    TYPE "trapped ", ERROR(-1, 0)
.END
.PROGRAM spin()
    n = 0
    WHILE n < 100 DO
        n = n + 1
        WAIT
    END
.END
"""
FILE = "dbg.V2"


@pytest.fixture()
def dbg(tmp_path):
    path = tmp_path / FILE
    path.write_text(SRC)
    emu = Emulator.load(path, robot=False)
    events: list = []
    d = Debugger(emu.rt, lambda name, body: events.append((name, body)))
    d.events, d.emu, d.path = events, emu, str(path)
    return d


def stopped_at(d, task=0):
    d.emu.run(5.0, until=lambda: task in d.stopped)
    assert task in d.stopped, d.emu.console
    f = d.frames(task)[0]
    return d.stopped[task].reason, f.program, f.line


def test_a_breakpoint_stops_with_the_stack_variables_and_evaluate_and_set(dbg):
    (bp,) = dbg.set_breakpoints(dbg.path, [{"line": 13}])     # the AUTO line: moved to the first statement
    assert bp.verified and (bp.program, bp.line) == ("add", 14)
    dbg.emu.execute(0, "main")
    assert stopped_at(dbg) == ("breakpoint", "add", 14)
    inner, outer = dbg.frames(0)
    assert (outer.program, outer.line, dbg.path_of(outer.file)) == ("main", 8, dbg.path)
    scopes = dbg.scopes(inner)
    assert scopes["AUTO"][:2] == [("x", 1.0), ("y", 1.0)]
    outer_scopes = dbg.scopes(outer)
    assert ("$s", "abc") in outer_scopes["AUTO"] and ("k", 1.0) in outer_scopes["LOCAL"]
    spot = dict(outer_scopes["Globals"])["spot"]
    assert render(spot) == "TRANS(10.000, 20.000, 30.000, 0.000, 90.000, 0.000)"
    assert [n for n, _ in children(spot)] == ["x", "y", "z", "yaw", "pitch", "roll"]
    loc = dbg.evaluate("SHIFT(spot BY 1, 2, 3)", inner)
    assert [round(v, 3) for v in loc.decompose()[:3]] == [11.0, 22.0, 33.0]
    assert dbg.evaluate("x + y * 10", inner) == 11.0
    assert dbg.evaluate('$s + "d"', outer) == "abcd"
    with pytest.raises(DebugError, match="Undefined value"):
        dbg.evaluate("nosuch + 1", inner)
    assert dbg.set_variable(inner, "x", "100") == 100.0            # x is main's a, by reference
    assert dbg.set_variable(outer, "$s", '"xyz"') == "xyz"
    dbg.set_breakpoints(dbg.path, [])
    dbg.resume(0)
    dbg.emu.run(5.0)
    assert dbg.emu.console[-1] == "[0] a=115"                     # 100 + 1 + 2 + 3 + 4 + 5


def test_conditions_hit_counts_and_logpoints(dbg):
    bps = dbg.set_breakpoints(dbg.path, [{"line": 15, "logMessage": "t is {t} ({y})"},
                                         {"line": 14, "condition": "y == 3"}])
    assert [b.line for b in bps] == [15, 14]
    dbg.emu.execute(0, "main")
    assert stopped_at(dbg) == ("breakpoint", "add", 14)
    assert dbg.evaluate("y", dbg.frames(0)[0]) == 3.0
    logs = [b["output"] for n, b in dbg.events if n == "output"]
    assert logs == ["t is 2 (1)\n", "t is 4 (2)\n"]
    dbg.set_breakpoints(dbg.path, [{"line": 14, "hitCondition": "2"}])     # from the 2nd hit on
    dbg.resume()
    assert stopped_at(dbg) == ("breakpoint", "add", 14)
    assert dbg.evaluate("y", dbg.frames(0)[0]) == 5.0                      # hits: y=4 (1st), y=5 (2nd)
    with pytest.raises(DebugError, match="hit count"):
        dbg.set_breakpoints(dbg.path, [{"line": 14, "hitCondition": "often"}])


def test_step_into_over_and_out(dbg):
    dbg.set_breakpoints(dbg.path, [{"line": 8}])
    dbg.emu.execute(0, "main")
    assert stopped_at(dbg) == ("breakpoint", "main", 8)
    dbg.set_breakpoints(dbg.path, [])
    dbg.step(0, "in")
    assert stopped_at(dbg) == ("step", "add", 14)
    dbg.step(0, "over")
    assert stopped_at(dbg) == ("step", "add", 15)
    dbg.step(0, "out")
    assert stopped_at(dbg)[:2] == ("step", "main")
    dbg.step(0, "over")                         # over the CALL: back at it (the FOR loops) without entering add
    reason, prog, line = stopped_at(dbg)
    assert (reason, prog) == ("step", "main") and line in (7, 8)


def test_an_error_stops_as_an_exception_before_reacte_by_the_mode(dbg):
    dbg.emu.execute(0, "bad")
    assert stopped_at(dbg) == ("exception", "bad", 18)
    assert "Division by 0" in dbg.stopped[0].text
    dbg.resume()
    dbg.emu.run(1.0)
    assert dbg.emu.task(0).state == "error"
    dbg.emu.execute(0, "trapped")               # untrapped mode (the default): REACTE takes it, no stop
    dbg.emu.run(1.0)
    assert 0 not in dbg.stopped and dbg.emu.console[-1] == "[0] went on"
    dbg.exceptions = "all"
    dbg.emu.execute(0, "trapped")
    assert stopped_at(dbg) == ("exception", "trapped", 23)
    dbg.resume()
    dbg.emu.run(1.0)
    assert dbg.emu.console[-1] == "[0] went on"


def test_a_stopped_task_stops_no_other_and_pause_stops_a_running_one(dbg):
    dbg.set_breakpoints(dbg.path, [{"line": 14}])
    dbg.emu.execute(0, "main")
    dbg.emu.execute(1, "spin")
    assert stopped_at(dbg) == ("breakpoint", "add", 14)
    dbg.emu.run(1.0)
    n = dbg.emu.globals["n"]
    assert n > 10                                          # task 1 ran on
    assert [t for t, _ in dbg.threads()] == [0, 1]
    dbg.pause(1)
    assert stopped_at(dbg, 1)[:2] == ("pause", "spin")
    n = dbg.emu.globals["n"]
    dbg.emu.run(1.0)
    assert dbg.emu.globals["n"] == n                       # paused: no progress
    dbg.resume()
    dbg.set_breakpoints(dbg.path, [])
    dbg.emu.run(5.0)
    assert dbg.emu.globals["n"] == 100.0 and dbg.emu.console[-1] == "[0] a=16"


MOVER = """.PROGRAM mover()
    HERE #p
    DECOMPOSE j[] = #p
    MOVE #PPOINT(j[0]+60, j[1], j[2], j[3], j[4], j[5])
    TYPE "moving"
    WAIT
    TYPE "on"
.END
"""


def _moving(tmp_path, bp_line: int | None):
    path = tmp_path / "mover.V2"
    path.write_text(MOVER)
    emu = Emulator.load(path)
    d = Debugger(emu.rt)
    if bp_line is not None:
        d.set_breakpoints(str(path), [{"line": bp_line}])
    emu.execute(0, "mover")
    return emu, d


def test_a_task_that_stops_during_a_motion_brakes_the_arm_and_ending_the_session_brakes_too(tmp_path):
    emu, d = _moving(tmp_path, 5)                 # stops right after the MOVE started
    emu.run(until=lambda: 0 in d.stopped)
    traj = emu.controller.trajectory
    j0 = emu.controller.joints_at(emu.time_s)[0]
    emu.run(2.0)                                  # far longer than a brake takes
    assert not traj.in_motion(emu.time_s)
    assert emu.controller.joints_at(emu.time_s)[0] < j0 + 10      # came to rest, far from the 60 degrees
    emu, d = _moving(tmp_path, None)              # no breakpoint: the session ends mid-motion
    emu.run(until=lambda: any("moving" in c for c in emu.console))
    assert emu.controller.trajectory.in_motion(emu.time_s)
    d.end()
    emu.run(2.0)
    assert not emu.controller.trajectory.in_motion(emu.time_s) and emu.task(0).state == "aborted"


def test_stop_on_entry_precision_points_and_setting_a_location(dbg):
    dbg.emu.execute(0, "main")
    dbg.stop_on_entry(0)
    assert stopped_at(dbg) == ("entry", "main", 4)                 # before the first statement (a = 1)
    f = dbg.frames(0)[0]
    pp = dbg.evaluate("#PPOINT(1, 2, 3, 4, 5, 6)", f)
    assert render(pp) == "#PPOINT(1.000, 2.000, 3.000, 4.000, 5.000, 6.000)"
    assert children(pp) == [("j1", 1.0), ("j2", 2.0), ("j3", 3.0), ("j4", 4.0), ("j5", 5.0), ("j6", 6.0)]
    loc = dbg.set_variable(f, "place", "TRANS(1, 2, 3, 0, 90, 0)")     # stored as SET would
    assert [round(v, 3) for v in loc.decompose()] == [1.0, 2.0, 3.0, 0.0, 90.0, 0.0]
    assert dbg.emu.globals["place"] is loc
    with pytest.raises(DebugError, match="not a variable"):
        dbg.set_variable(f, "1 + 2", "3")
    dbg.resume(0)
    dbg.emu.run(5.0)
    assert dbg.emu.console[-1] == "[0] a=16"
