"""Command values are refused at construction (ValueError naming the field) before anything can reach the wire:
non-finite or absurd numbers, speed 0, and every accepted motion fits the 128-character V+ line.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept import MoveJoints, MoveRelJoints, MoveRelTool, MoveRelWorld, MoveTo, MoveToolZ, SetSpeed, Skill
from aioadept.commands import MAX_ABS_DEG, MAX_ABS_MM
from aioadept.protocol import MAX_LINE, SkillCall, encode_command

POSE_CLASSES = (MoveTo, MoveRelWorld, MoveRelTool)
JOINT_CLASSES = (MoveJoints, MoveRelJoints)


@pytest.mark.parametrize("make,field", [
    (lambda: MoveTo([1e308, 0, 500, 0, 180, 0]), r"pose\[0\]"),
    (lambda: MoveTo([300, 0, 500, 0, 1e20, 0]), r"pose\[4\]"),
    (lambda: MoveRelTool([0, 0, 0, 0, 0, -1e20]), r"delta\[5\]"),
    (lambda: MoveRelWorld([0, MAX_ABS_MM * 1.0001, 0, 0, 0, 0]), r"delta\[1\]"),
    (lambda: MoveJoints([0, 0, 0, 0, 0, 1e5]), r"joints_deg\[5\]"),       # 1e5 is a fine length, not an angle
    (lambda: MoveRelJoints([-1e20, 0, 0, 0, 0, 0]), r"delta_joints_deg\[0\]"),
    (lambda: MoveToolZ(1e308), "delta_z_mm"),
    (lambda: MoveToolZ(-math.inf), "delta_z_mm"),
    (lambda: SetSpeed(0), "speed"),
    (lambda: SetSpeed(0.0), "speed"),
    (lambda: SetSpeed(10**30), "speed"),
    (lambda: SetSpeed(math.inf), "speed"),
    (lambda: Skill("move_rel_tool", 0, 0, 1e20, 0, 0, 0), r"args\[2\]"),   # short enough for a line, still absurd
    (lambda: Skill("move_joints", 2e4), r"args\[0\]"),
    (lambda: Skill("x", 1e308), "args"),                                   # any skill: the line limit
])
def test_absurd_values_are_refused_naming_the_field(make, field):
    with pytest.raises(ValueError, match=f"^{field}"):
        make()


def test_the_bounds_themselves_are_accepted_and_fit_the_line():
    for cls in POSE_CLASSES:
        call = cls([-MAX_ABS_MM] * 3 + [-MAX_ABS_DEG] * 3, break_move=False).calls()[0]
        assert len(encode_command("ffffffff", call)) <= MAX_LINE + 2
    for cls in JOINT_CLASSES:
        call = cls([-MAX_ABS_DEG] * 6, break_move=False).calls()[0]
        assert len(encode_command("ffffffff", call)) <= MAX_LINE + 2
    assert SetSpeed(1).speed == 1 and SetSpeed(100).speed == 100
    # Skill is the raw path: the server judges argument counts and set_speed values
    assert Skill("set_speed", 0).calls() == (SkillCall("set_speed", (0,)),)
    assert Skill("move_to", 1.0, 2.0).calls()[0].args == (1.0, 2.0)


_real = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**30, 10**30))


@settings(max_examples=300, deadline=None)
@given(cls=st.sampled_from(POSE_CLASSES + JOINT_CLASSES), values=st.lists(_real, min_size=6, max_size=6))
def test_any_six_numbers_either_build_a_line_within_128_or_raise_value_error(cls, values):
    """Property: a motion command is built only from finite values within the bounds, and its line always fits."""
    units = (["mm"] * 3 + ["deg"] * 3) if cls in POSE_CLASSES else ["deg"] * 6
    limit = {"mm": MAX_ABS_MM, "deg": MAX_ABS_DEG}
    ok = all(math.isfinite(float(v)) and abs(float(v)) <= limit[u] for v, u in zip(values, units, strict=True))
    try:
        cmd = cls(values)
    except ValueError:
        assert not ok
        return
    assert ok
    line = encode_command("ffffffff", cmd.calls()[0])
    assert len(line) <= MAX_LINE + 2
    assert all(math.isfinite(a) for a in cmd.calls()[0].args)


@settings(max_examples=200, deadline=None)
@given(speed=st.one_of(st.integers(-10**6, 10**6), st.floats(allow_nan=True, allow_infinity=True)))
def test_set_speed_is_an_integer_in_1_to_100_or_value_error(speed):
    valid = math.isfinite(speed) and float(speed).is_integer() and 0 < speed <= 100
    try:
        cmd = SetSpeed(speed)
    except ValueError:
        assert not valid
        return
    assert valid and cmd.calls()[0].args == (int(speed),) and type(cmd.calls()[0].args[0]) is int
