"""fast_constructor builds exactly the object the dataclass's own constructor builds (type, equality, hash)."""

from __future__ import annotations

import copy
import dataclasses
import pickle

import pytest

from aioadept.geometry import Pose
from aioadept.protocol import Ack, Status
from aioadept.protocol.messages import fast_constructor

FIELDS = ("id", "status", "t_start_s", "t_done_s", "pose", "extra")


def test_built_ack_is_an_ack_equal_to_the_constructed_one():
    make = fast_constructor(Ack, FIELDS)
    pose = Pose(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    got = make("abcdef12", Status.DONE, 1.5, 2.5, pose, ("x",))
    want = Ack("abcdef12", Status.DONE, 1.5, 2.5, pose, ("x",))
    assert type(got) is Ack
    assert got == want and want == got and hash(got) == hash(want) and repr(got) == repr(want)
    assert got != Ack("abcdef12", Status.DONE, 1.5, 2.6, pose, ("x",))
    assert pickle.loads(pickle.dumps(got)) == want
    assert copy.copy(got) == want
    assert dataclasses.replace(got, id="00000001").id == "00000001"
    with pytest.raises(dataclasses.FrozenInstanceError):
        got.id = "00000002"  # type: ignore[misc]


def test_wrong_shape_falls_back_to_the_class():
    assert fast_constructor(Ack, FIELDS[:-1]) is Ack

    @dataclasses.dataclass(frozen=True)
    class NoSlots:
        a: int

    assert fast_constructor(NoSlots, ("a",)) is NoSlots

    @dataclasses.dataclass(frozen=True, slots=True)
    class Checked:
        a: int

        def __post_init__(self) -> None:
            raise ValueError

    assert fast_constructor(Checked, ("a",)) is Checked
