"""Command classes: what they expand to, their repr, immutability and validation (ValueError naming the field)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aioadept import (
    Break,
    DisableAir,
    EnableAir,
    Here,
    Joined,
    MoveJoints,
    MoveRelJoints,
    MoveRelTool,
    MoveRelWorld,
    MoveTo,
    MoveToolZ,
    Pose,
    SetSpeed,
    Skill,
)
from aioadept.protocol import SkillCall, encode_command

SIX = (1.0, -2.0, 3.5, 0.0, 90.0, 180.0)


@pytest.mark.parametrize(
    ("cls", "skill"),
    [(MoveTo, "move_to"), (MoveJoints, "move_joints"), (MoveRelWorld, "move_rel_world"),
     (MoveRelTool, "move_rel_tool"), (MoveRelJoints, "move_rel_joints")],
)
def test_motion_commands_append_break_by_default(cls, skill):
    assert cls(SIX).calls() == (SkillCall(skill, SIX), SkillCall("break"))
    assert cls(SIX, break_move=False).calls() == (SkillCall(skill, SIX),)
    assert len(cls(SIX)) == 2
    assert cls(SIX).values == SIX


def test_paper_init_move_and_move_tool_z_wire_bytes():
    wire = [encode_command("%08x" % i, c) for i, c in enumerate(
        Joined(MoveJoints([0, -90, 180, 0, 90, 0]), SetSpeed(20), MoveToolZ(-2.5)).calls(), start=1)]
    assert wire == [
        b"00000001:move_joints:0.000,-90.000,180.000,0.000,90.000,0.000\r\n",
        b"00000002:break\r\n",
        b"00000003:set_speed:20\r\n",
        b"00000004:move_rel_tool:0.000,0.000,-2.500,0.000,0.000,0.000\r\n",
        b"00000005:break\r\n",
    ]


def test_simple_commands():
    assert Break().calls() == (SkillCall("break"),)
    assert EnableAir().calls() == (SkillCall("enable_air"),)
    assert DisableAir().calls() == (SkillCall("disable_air"),)
    assert Here().calls() == (SkillCall("here"),)
    assert SetSpeed(100).calls() == (SkillCall("set_speed", (100,)),)
    assert SetSpeed(7.0).speed == 7 and SetSpeed(np.int64(5)).speed == 5
    assert Skill("open_gripper").calls() == (SkillCall("open_gripper"),)
    assert Skill("set_tool", 0, 0, 120.5).calls()[0].wire == "set_tool:0,0,120.500"
    assert MoveToolZ(2.5).delta_z_mm == 2.5
    assert MoveTo(Pose(*SIX)) == MoveTo(SIX)
    assert MoveTo(np.array(SIX)).values == SIX


def test_repr_is_useful():
    assert repr(MoveTo(SIX)) == "MoveTo([1, -2, 3.5, 0, 90, 180])"
    assert repr(MoveToolZ(2.5, break_move=False)) == "MoveToolZ(2.5, break_move=False)"
    assert repr(SetSpeed(20)) == "SetSpeed(20)"
    assert repr(Skill("grip", 1, 2.5)) == "Skill('grip', 1, 2.5)"
    assert repr(Joined(SetSpeed(20), Break())) == "Joined(SetSpeed(20), Break())"


def test_commands_are_immutable_and_hashable():
    c = MoveTo(SIX)
    with pytest.raises(AttributeError):
        c.foo = 1  # type: ignore[attr-defined]
    with pytest.raises(AttributeError):
        c._calls = ()  # type: ignore[misc]
    assert hash(MoveTo(SIX)) == hash(MoveTo(list(SIX)))
    assert MoveTo(SIX) != MoveRelWorld(SIX)
    assert {SetSpeed(1), SetSpeed(1)} == {SetSpeed(1)}


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: MoveTo([1, 2, 3]), "pose"),
        (lambda: MoveTo([1, 2, 3, 4, 5, math.nan]), r"pose\[5\]"),
        (lambda: MoveTo([1, 2, 3, 4, 5, "6"]), r"pose\[5\]"),
        (lambda: MoveTo([1, 2, True, 4, 5, 6]), r"pose\[2\]"),
        (lambda: MoveJoints([0, 0, 0, 0, 0, math.inf]), r"joints_deg\[5\]"),
        (lambda: MoveRelJoints([0] * 7), "delta_joints_deg"),
        (lambda: MoveRelTool([0] * 5), "delta"),
        (lambda: MoveToolZ(math.nan), "delta_z_mm"),
        (lambda: MoveToolZ("1"), "delta_z_mm"),
        (lambda: SetSpeed(101), "speed"),
        (lambda: SetSpeed(-1), "speed"),
        (lambda: SetSpeed(2.5), "speed"),
        (lambda: SetSpeed(True), "speed"),
        (lambda: SetSpeed(math.nan), "speed"),
        (lambda: Skill("Bad_Name"), "skill"),
        (lambda: Skill("a" * 16), "skill"),
        (lambda: Skill("9lives"), "skill"),
        (lambda: Skill("with:colon"), "skill"),
        (lambda: Skill("x", math.nan), r"args\[0\]"),
        (lambda: Skill("x", "1"), r"args\[0\]"),
        (lambda: Skill("x", *([1000] * 30)), "args"),                    # line over 128 characters
        (lambda: Skill("move_to", *([123456.789] * 12)), "args"),
        (lambda: Joined(SetSpeed(1), "break"), r"commands\[1\]"),  # type: ignore[arg-type]
    ],
)
def test_validation_names_the_field(make, field):
    with pytest.raises(ValueError, match=f"^{field}"):
        make()


def test_longest_allowed_line_is_128():
    call = Skill("s", *([1] * 59)).calls()[0]     # "s:" + 59 ones and 58 commas = 119 -> 8 + 1 + 119 = 128
    assert len(encode_command("00000001", call)) == 128 + 2
    with pytest.raises(ValueError, match="args"):
        Skill("s", *([1] * 60))
