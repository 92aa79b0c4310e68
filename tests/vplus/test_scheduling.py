"""When blocked tasks wake, in virtual time: WAIT cond re-tested when another task has run, SET.EVENT waking
WAIT.EVENT at once, no busy loop between tasks that wait on each other (docs/vplus.md, "Tasks")."""

from __future__ import annotations

import pytest


def test_wait_condition_wakes_when_another_task_sets_the_global_not_at_the_next_cycle(emu_of):
    emu = emu_of(""".PROGRAM waiter()
	WAIT flag
	t1 = TIMER(-3)
.END
.PROGRAM setter()
	WAIT.EVENT 0, 0.005
	flag = TRUE
	t2 = TIMER(-3)
.END
""")
    emu.globals["flag"] = 0
    emu.execute(1, "waiter")
    emu.execute(2, "setter")
    emu.run(1.0)
    assert emu.globals["t2"] == pytest.approx(0.005, abs=1e-4)
    # V+ re-tests a false WAIT condition whenever the task is scheduled again; the cycle (16 ms) is only the
    # fallback for conditions on time
    assert emu.globals["t1"] == pytest.approx(emu.globals["t2"], abs=1e-4)


def test_wait_condition_on_time_is_re_tested_each_cycle(emu_of):
    emu = emu_of(".PROGRAM p()\n\tWAIT TIMER(-3) > 0.02\n\tt = TIMER(-3)\n.END\n")
    emu.call("p")
    assert emu.globals["t"] == pytest.approx(0.032, abs=1e-4)


def test_set_event_wakes_wait_event_at_once_and_the_flag_is_not_lost(emu_of):
    emu = emu_of(""".PROGRAM waiter()
	WAIT.EVENT 1, 10
	t1 = TIMER(-3)
	WAIT.EVENT 0, 0.01
	WAIT.EVENT 1, 10
	t3 = TIMER(-3)
.END
.PROGRAM setter()
	WAIT.EVENT 0, 0.003
	SET.EVENT 1
	WAIT.EVENT 0, 0.005
	SET.EVENT 1
.END
""")
    emu.execute(1, "waiter")
    emu.execute(2, "setter")
    emu.run(20.0)
    assert emu.globals["t1"] == pytest.approx(0.003, abs=1e-4)
    # the second SET.EVENT (at 8 ms) came while task 1 waited for something else: the flag stayed set and its
    # next WAIT.EVENT (at 13 ms) returned at once
    assert emu.globals["t3"] == pytest.approx(0.013, abs=1e-4)


def test_wait_event_times_out_without_an_event(emu_of):
    emu = emu_of(".PROGRAM p()\n\tWAIT.EVENT 1, 0.25\n\tt = TIMER(-3)\n.END\n")
    emu.call("p")
    assert emu.globals["t"] == pytest.approx(0.25, abs=1e-4)


def test_tasks_waiting_on_each_other_do_not_spin_and_time_moves_on(emu_of):
    emu = emu_of(""".PROGRAM a()
	WAIT b.go
.END
.PROGRAM b()
	WAIT a.go
.END
""")
    emu.globals["a.go"] = 0
    emu.globals["b.go"] = 0
    emu.execute(1, "a")
    emu.execute(2, "b")
    emu.run(2.0)           # would raise "round limit reached" if each failed re-test woke the other
    assert emu.time_s == pytest.approx(2.0)
    assert emu.task(1).state == "running" and emu.task(2).state == "running"
    emu.globals["a.go"] = 1
    emu.globals["b.go"] = 1
    emu.run(0.1)
    assert emu.task(1).state == "done" and emu.task(2).state == "done"


def test_a_busy_task_does_not_starve_a_condition_waiter(emu_of):
    emu = emu_of(""".PROGRAM busy()
	FOR i = 1 TO 100000
	    n = i
	END
	done = TRUE
.END
.PROGRAM waiter()
	WAIT n >= 3000
	seen = n
.END
""")
    emu.globals["n"] = 0
    emu.execute(1, "waiter")
    emu.execute(2, "busy")
    emu.run(10.0)
    assert emu.globals["done"] == -1.0
    # re-tested after each slice of the busy task (2000 iterations), not after it finished
    assert 3000 <= emu.globals["seen"] < 100000
