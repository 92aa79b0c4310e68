"""STATE() as the V+ Reference Guide defines it: select 2 is 5 while the arm decelerates after a
BRAKE and 6 once it has stopped that way (not 1 and 2, which a finished motion gives), until the next motion;
select 3 is computer control; a select whose table we could not read is refused, not guessed."""

from __future__ import annotations

import pytest

from aioadept.vplus import Emulator, VPlusError

PROGRAM = """.PROGRAM t()
	SET p = HERE
	a0 = STATE(2)
	MOVE SHIFT(p BY 0, 0, -300)
	WAIT.EVENT , 0.05
	a1 = STATE(2)
	BRAKE
	a5 = STATE(2)
	BREAK
	a6 = STATE(2)
	WAIT.EVENT , 0.2
	a6b = STATE(2)
	MOVE p
	b1 = STATE(2)
	BREAK
	b2 = STATE(2)
	BRAKE
	c6 = STATE(2)
	m = STATE(3)
	f = STATE(4)
	o = STATE(1)
.END
"""


def test_state_2_tells_a_braked_stop_from_a_finished_motion():
    emu = Emulator.from_source(PROGRAM, filename="s.V2", strict=True)
    emu.call("t")
    g = emu.globals
    assert (g["a0"], g["a1"]) == (0.0, 1.0)
    assert (g["a5"], g["a6"], g["a6b"]) == (5.0, 6.0, 6.0)     # decelerating, then stopped, by the BRAKE
    assert (g["b1"], g["b2"]) == (1.0, 2.0)                    # the next motion, and its planned end
    assert g["c6"] == 6.0       # a BRAKE at rest: not "at a planned location" (the safe reading)
    assert (g["m"], g["f"], g["o"]) == (5.0, 0.0, 7.0)


@pytest.mark.parametrize("sel", [5, 9])
def test_a_select_whose_table_we_could_not_read_is_refused(sel):
    emu = Emulator.from_source(f".PROGRAM t()\n\tx = STATE({sel})\n.END\n", filename="s.V2", strict=True)
    with pytest.raises(VPlusError, match=rf"STATE\({sel}\) is not implemented by the emulator"):
        emu.call("t")
