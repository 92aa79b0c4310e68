"""TIMER n = value (V+ Language Reference Guide, TIMER program instruction): every form parses and sets the timer.

"TIMER timer_number = time_value": the number is an expression rounded to an integer, 1 to 15 (timer 0 is the
system clock and cannot be set); the value may be negative or have fractions (the manual's own timeout idiom:
``TIMER 1 = -delay`` then ``WAIT TIMER(1) > 0``).
"""

from __future__ import annotations

import pytest

from aioadept.vplus import VPlusError


@pytest.mark.parametrize("line", ["TIMER 1 = 0", "TIMER (1) = 0", "TIMER k = 0", "TIMER k-1+1 = 0",
                                  "TIMER 1 = t0-t0", "TIMER 1=0", "TIMER 1.4 = 0"])
def test_every_form_of_timer_assignment_parses_and_sets_timer_1(emu_of, line):
    emu = emu_of(f".PROGRAM p()\n\tk = 1\n\tt0 = 5\n\tWAIT.EVENT , 0.5\n\t{line}\n\tWAIT.EVENT , 0.25\n\tx = TIMER(1)\n.END\n")
    emu.call("p")
    assert emu.globals["x"] == pytest.approx(0.25, abs=0.002)


def test_the_manuals_timeout_idiom_waits_for_the_delay(emu_of):
    emu = emu_of(".PROGRAM p()\n\tdelay = 0.3\n\tTIMER 2 = -delay\n\tt = TIMER(-3)\n\tWAIT TIMER(2) > 0\n"
                 "\tdt = TIMER(-3)-t\n\tTIMER 3 = TIMER(2)+10\n\ty = TIMER(3)\n.END\n")
    emu.call("p")
    assert emu.globals["dt"] == pytest.approx(0.3, abs=0.02)
    assert emu.globals["y"] == pytest.approx(10, abs=0.02)


@pytest.mark.parametrize("n", ["0", "16", "-1"])
def test_a_timer_number_outside_1_to_15_is_an_error_naming_it(emu_of, n):
    emu = emu_of(f".PROGRAM p()\n\tTIMER {n} = 0\n.END\n")
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert "Illegal value" in str(info.value) and "timer" in str(info.value).lower()
