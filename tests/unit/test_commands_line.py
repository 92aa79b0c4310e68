"""The straight-line and approach commands: what they send and what they refuse before sending."""

from __future__ import annotations

import math

import pytest

from aioadept.commands import Appro, Appros, Depart, Departs, MoveRelToolS, MoveToS, Skill
from aioadept.geometry import Pose
from aioadept.protocol import SkillCall, encode_command

SIX = (400.0, 0.0, 400.0, 0.0, 180.0, 0.0)


@pytest.mark.parametrize(("cls", "skill"), [(MoveToS, "move_to_s"), (MoveRelToolS, "move_rel_tool_s")])
def test_straight_line_forms_of_the_paper_skills(cls, skill):
    assert cls(SIX).calls() == (SkillCall(skill, SIX), SkillCall("break"))
    assert cls(SIX, break_move=False).calls() == (SkillCall(skill, SIX),)


def test_appro_and_depart_wire_bytes():
    calls = [*Appro(Pose(*SIX), 50).calls(), *Appros(SIX, 20, break_move=False).calls(), *Depart(30).calls(),
             *Departs(-10, break_move=False).calls()]
    wire = [encode_command("%08x" % i, c) for i, c in enumerate(calls, start=1)]
    assert wire == [b"00000001:appro:400.000,0.000,400.000,0.000,180.000,0.000,50.000\r\n", b"00000002:break\r\n",
                    b"00000003:appros:400.000,0.000,400.000,0.000,180.000,0.000,20.000\r\n",
                    b"00000004:depart:30.000\r\n", b"00000005:break\r\n", b"00000006:departs:-10.000\r\n"]
    assert Appro(SIX, 50).pose == Pose(*SIX) and Appro(SIX, 50).distance_mm == 50.0
    assert repr(Departs(2.5, break_move=False)) == "Departs(2.5, break_move=False)"


@pytest.mark.parametrize("make", [
    lambda: Appro(SIX[:5], 10), lambda: Appro(SIX, math.nan), lambda: Appros(SIX, "10"), lambda: Depart(True),
    lambda: Departs(math.inf), lambda: Depart(1e6), lambda: MoveToS((*SIX[:3], 1e9, 0, 0)),
    lambda: Skill("appros", *SIX, 1e9), lambda: Skill("departs", math.nan), lambda: Skill("move_to_s", 1e9),
])
def test_bad_values_are_refused_before_anything_is_sent(make):
    with pytest.raises(ValueError):
        make()
