"""The ``.LOCATIONS`` section as a controller's STORE writes it.

A transformation is stored as the 12 components of its 3x4 matrix by column (V+ Language Reference Guide,
``TRANSB``/``$TRANSB``: "a 3-by-4 transformation matrix, stored by column"), written over two lines, the second
without a name. Loading must give exactly that location, or refuse it by name: never another value.
"""

from __future__ import annotations

import math

import pytest

from aioadept.vplus import Emulator, VPlusError

# test_1: the tool pointing down (x axis (1,0,0), y axis (0,-1,0), z axis (0,0,-1)) at 480, 0, 500;
# test_2: turned 90 degrees about the world z axis (x axis (0,1,0), y axis (1,0,0), z axis (0,0,-1)) at 300, -200, 250
STORED = """.PROGRAM p()
\tDECOMPOSE a[] = test_1
\tDECOMPOSE b[] = test_2
\tDECOMPOSE c[] = #pp
.END
.LOCATIONS

test_1                 1 0 0 0 -1 0
                       0 0 -1 480 0 500
test_2                 0 1 0 1 0 0
                       0 0 -1 300 -200 250
#pp                    10 -90 180
                       0 90 5
.END
"""


def decomposed(emu, name):
    return [emu.globals[name][i] for i in range(6)]


def test_a_stored_transformation_over_two_lines_loads_as_its_matrix():
    emu = Emulator.from_source(STORED, filename="cell.V2", robot=False, strict=True)
    emu.call("p")
    x, y, z, yaw, pitch, roll = decomposed(emu, "a")
    assert (x, y, z) == pytest.approx((480, 0, 500), abs=1e-3)
    assert abs(pitch) == pytest.approx(180, abs=1e-3)
    m = emu.globals["test_2"].matrix
    assert [m[0][3], m[1][3], m[2][3]] == pytest.approx([300, -200, 250])
    # by column: the first three numbers are the x axis, i.e. the first column of the rotation
    assert [m[0][0], m[1][0], m[2][0]] == pytest.approx([0, 1, 0])
    assert [m[0][1], m[1][1], m[2][1]] == pytest.approx([1, 0, 0])
    assert decomposed(emu, "c") == pytest.approx([10, -90, 180, 0, 90, 5])


@pytest.mark.parametrize("entry, why", [
    ("test_1 1 0 0 0 -1 0\n   0 0 -1 480 0", "got 11"),                   # a value missing
    ("test_1 1 0 0 0 -1 0\n   0 0 -1 480 0 500 7", "got 13"),
    ("test_1 1 0 0 0 1 0\n   0 0 -1 480 0 500", "reflection"),           # left-handed
    ("test_1 1 0 0 0 -2 0\n   0 0 -1 480 0 500", "orthonormal"),          # not a rotation
    ("test_1 0 -1 0 0 0", "got 5"),
    ("test_1 1 0 0 0 -1 0\n   0 0 -1 nan 0 500", "finite"),
])
def test_a_location_that_cannot_be_read_exactly_is_refused_by_name_and_stays_undefined(entry, why):
    src = ".PROGRAM p()\n\tDECOMPOSE a[] = test_1\n.END\n.LOCATIONS\n" + entry + "\nok 1 2 3 0 0 0\n.END\n"
    emu = Emulator.from_source(src, filename="cell.V2", robot=False)
    [problem] = emu.problems
    assert (problem.file, problem.line, problem.word) == ("cell.V2", 5, "test_1")
    assert "test_1" in problem.message and why in problem.message
    assert "test_1" not in emu.globals and "ok" in emu.globals
    with pytest.raises(VPlusError) as info:
        emu.call("p")
    assert "Undefined value" in str(info.value) and "test_1" in str(info.value)


def test_values_without_a_name_are_a_problem():
    emu = Emulator.from_source(".LOCATIONS\n 1 2 3 0 0 0\n.END\n", filename="cell.V2", robot=False)
    assert [(p.line, p.word) for p in emu.problems] == [(2, "1")]


def test_the_one_line_shorthand_still_reads_x_y_z_yaw_pitch_roll():
    emu = Emulator.from_source(".LOCATIONS\nloc1 100 200 300 0 180 0\n.END\n", filename="c.V2", robot=False,
                               strict=True)
    p = emu.globals["loc1"].to_pose()
    assert (p.x, p.y, p.z) == pytest.approx((100, 200, 300)) and math.isclose(abs(p.pitch), 180, abs_tol=1e-6)
