"""The V+ state stream's line format (aioadept.protocol.statestream) and the V+ task that writes it
(vplus/rsstate.V2, run on the emulator in virtual time): what one writes the other reads."""

from __future__ import annotations

from pathlib import Path

import pytest

from aioadept.client.statestream import to_robot_state
from aioadept.errors import RemoteProtocolError
from aioadept.geometry import Pose
from aioadept.protocol.statestream import StateSample, encode_state_line, parse_state_line
from aioadept.vplus import Emulator

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
LINE = ("S1 t=12.345 j=0.000,-90.000,180.000,0.000,90.000,0.000 p=480.000,0.000,710.000,0.000,180.000,0.000 "
        "mv=1 sp=30 er=-1003 air=1")


def test_a_full_line_parses_to_every_field():
    s = parse_state_line(LINE.encode())
    assert s == StateSample(12.345, (0.0, -90.0, 180.0, 0.0, 90.0, 0.0), Pose(480, 0, 710, 0, 180, 0),
                            moving=True, speed_pct=30.0, error_code=-1003, air=True)
    assert parse_state_line(encode_state_line(s)[:-2]) == s


def test_unknown_fields_are_kept_and_optional_ones_default():
    s = parse_state_line("S1 t=1 j=1,2,3,4,5,6 p=1,2,3,4,5,6 io=1001,-1002 hand=closed")
    assert s is not None
    assert dict(s.extra) == {"io": "1001,-1002", "hand": "closed"}
    assert (s.moving, s.speed_pct, s.error_code, s.air) == (False, 100.0, 0, False)
    assert b"io=1001,-1002" in encode_state_line(s)


@pytest.mark.parametrize("line", ["", "S2 t=1 whatever", "hello", "   "])
def test_lines_of_another_kind_are_skipped(line):
    assert parse_state_line(line) is None


@pytest.mark.parametrize("line, why", [
    ("S1 j=1,2,3,4,5,6 p=1,2,3,4,5,6", "no t="),
    ("S1 t=1 j=1,2,3,4,5 p=1,2,3,4,5,6", "j needs 6"),
    ("S1 t=1 j=1,2,3,4,5,6 p=1,2,3,4,5,x", "not a number"),
    ("S1 t=nan j=1,2,3,4,5,6 p=1,2,3,4,5,6", "not finite"),
    ("S1 t=1 j=1,2,3,4,5,6 p=1,2,3,4,5,6 mv", "not key=value"),
])
def test_malformed_lines_raise_with_the_reason(line, why):
    with pytest.raises(RemoteProtocolError, match=why):
        parse_state_line(line)


def test_the_bus_message_carries_the_sample():
    s = parse_state_line(LINE)
    assert s is not None
    st = to_robot_state(s, 1000.0)
    assert (st.t_s, st.wall_time_s, st.joints_deg, st.pose) == (12.345, 1000.0, s.joints_deg, s.pose)
    assert st.in_motion and st.speed_pct == 30 and st.air


def test_the_v_plus_task_writes_lines_this_module_reads():
    emu = Emulator.load(*(VPLUS / f for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2", "rsstate.V2")),
                        strict=True)
    emu.call("rs.init")
    emu.call("move_joints", [10, -80, 170, 5, 80, 20], attach=True)
    mid = emu.call("rs.stline", "", "", "")
    emu.call("break", attach=True)
    emu.call("enable_air", attach=True)
    rest = emu.call("rs.stline", "", "", "")
    for r in (mid, rest):
        assert all(len(part) <= 128 for part in r.args)        # V+ strings
    a = parse_state_line("".join(mid.args))
    b = parse_state_line("".join(rest.args))
    assert a is not None and b is not None
    assert a.moving and not b.moving
    assert b.joints_deg == pytest.approx((10, -80, 170, 5, 80, 20), abs=1e-3)
    assert b.air and not a.air and b.error_code == 0 and b.speed_pct == 100
    assert b.t_s > a.t_s
