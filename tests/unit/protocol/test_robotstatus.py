"""The ``status`` ack's fields (docs/protocol.md, 4.7): encoding and parsing agree, and bad fields are refused."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from aioadept.errors import RemoteProtocolError
from aioadept.protocol.robotstatus import (HAND_CODES, RobotStatus, encode_status_fields, hand_of_valves,
                                           parse_status_fields)


@given(st.booleans(), st.integers(1, 100), st.integers(-10000, 0), st.none() | st.booleans(),
       st.none() | st.booleans(), st.none() | st.sampled_from(sorted(HAND_CODES)))
def test_encode_then_parse_gives_the_status_back(moving, speed, code, power, estop, hand):
    status = RobotStatus(moving, float(speed), code, "", power, estop, hand)
    pairs, text = encode_status_fields(status)
    assert parse_status_fields((pairs, text) if text else (pairs,)) == status


def test_the_hand_of_the_valves():
    assert [hand_of_valves(o, c) for o, c in ((1, 0), (0, 1), (0, 0), (1, 1))] == ["open", "closed", "relaxed",
                                                                                  "both"]


def test_an_older_server_without_hd_reads_as_none_and_an_unknown_key_is_kept():
    st_ = parse_status_fields(("mv=0,sp=50,er=0,zz=3",))
    assert st_.hand is None and dict(st_.extra) == {"zz": "3"}


@pytest.mark.parametrize("bad", ["mv=0,sp=1,hd=q", "mv=0,sp=1,hd=", "mv=0,hd=o", "mv=x,sp=1"])
def test_bad_fields_are_refused(bad):
    with pytest.raises(RemoteProtocolError):
        parse_status_fields((bad,))


def test_the_time_scale_round_trips_and_a_server_without_ts_reads_as_none():
    status = RobotStatus(False, 100.0, 0, "", True, False, "relaxed", time_scale=5.0)
    pairs, _ = encode_status_fields(status)
    assert pairs.endswith(",ts=5") and parse_status_fields((pairs,)) == status
    assert parse_status_fields(("mv=0,sp=100,er=0",)).time_scale is None


@pytest.mark.parametrize("bad", ["mv=0,sp=1,ts=0", "mv=0,sp=1,ts=-2", "mv=0,sp=1,ts=x", "mv=0,sp=1,ts=inf"])
def test_a_time_scale_not_above_zero_is_refused(bad):
    with pytest.raises(RemoteProtocolError):
        parse_status_fields((bad,))
