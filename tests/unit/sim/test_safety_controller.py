"""Safety promises of the pure controller, with a fake clock.

Each test here failed on the controller before the fix it checks: see docs/security.md, "Safety promises".
"""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.protocol import NO_ID, ErrorCode, Status, parse_command
from aioadept.errors import RemoteProtocolError
from aioadept.sim.motion import plan_duration

from test_sim_controller import HOME, Rig  # the shared fake-clock rig (same folder, on sys.path under pytest)


@pytest.fixture
def rig():
    r = Rig()
    r.connect("a", "b", "c")
    return r


def j1_duration(delta, speed=100):
    return plan_duration([delta, 0, 0, 0, 0, 0], speed / 100)[0]


# -- 1. a disconnected client's queued commands never run -------------------------------------------------------

def test_disconnect_after_the_first_motion_drops_the_second_before_it_can_start(rig):
    # A long move, then a second move queued behind it; the client dies while the first still runs.
    rig.send("a", "move_joints", 100, -90, 180, 0, 90, 0, now=0.0)
    rig.send("a", "move_joints", -100, -90, 180, 0, 90, 0, now=0.0)
    t_blend = j1_duration(100) - 0.1  # when the second would start (the first begins to decelerate)
    # The disconnect is noticed after the second motion's slot came: it must still never start.
    rig.ctl.disconnect("a", now=t_blend + 0.05)
    rig.run_until_idle()
    assert rig.ctl.joints_at(20.0)[0] == pytest.approx(100.0)
    assert rig.ctl.queued() == 0 and not rig.ctl.busy


def test_disconnect_keeps_other_clients_commands(rig):
    rig.send("a", "move_joints", 40, -90, 180, 0, 90, 0, now=0.0)
    rig.send("a", "move_joints", 80, -90, 180, 0, 90, 0, now=0.0)
    b = rig.send("b", "break", now=0.0)
    rig.ctl.disconnect("a", now=0.05)
    rig.run_until_idle()
    assert rig.ack("b", b).status is Status.DONE
    assert rig.ctl.joints_at(20.0)[0] == pytest.approx(40.0)


# -- 2. three stops in a row ------------------------------------------------------------------------------------

def test_three_stops_in_a_row_are_each_acked_done_at_rest(rig):
    rig.send("a", "move_joints", 150, -90, 180, 0, 90, 0, now=0.0)
    brk = rig.send("a", "break", now=0.0)
    stops = [rig.send(c, "stop", now=0.3 + 0.01 * i) for i, c in enumerate("abc")]
    assert rig.ack("a", brk).status is Status.ABORTED
    rig.run_until_idle()
    acks = [rig.ack(c, s) for c, s in zip("abc", stops, strict=True)]
    assert [a.status for a in acks] == [Status.DONE] * 3, acks
    t_rest = rig.ctl.trajectory.t_rest_s
    assert all(a.t_done_s == pytest.approx(t_rest, abs=1e-3) for a in acks)
    assert not rig.ctl.trajectory.in_motion(acks[-1].t_done_s)


def test_a_stop_never_aborts_a_stop_and_later_commands_still_run(rig):
    rig.send("a", "move_joints", 150, -90, 180, 0, 90, 0, now=0.0)
    s1 = rig.send("a", "stop", now=0.3)
    s2 = rig.send("a", "stop", now=0.31)
    h = rig.send("b", "move_joints", *HOME, now=0.32)
    s3 = rig.send("c", "stop", now=0.33)  # aborts b's move, not the stops
    rig.run_until_idle()
    assert rig.ack("b", h).status is Status.ABORTED
    assert [rig.ack(c, s).status for c, s in (("a", s1), ("a", s2), ("c", s3))] == [Status.DONE] * 3


# -- 6. values are validated ------------------------------------------------------------------------------------

@pytest.mark.parametrize("speed", [0.001, 1e-101, 0.5, 0, -1, 100.5, 1e15])
def test_set_speed_outside_the_range_or_below_the_minimum_is_refused(rig, speed):
    mid = rig.send("a", "set_speed", speed, now=0.0) if speed != 1e-101 else None
    if mid is None:  # %.3f would print 0.000: send the exponent-free long form
        mid = "0000beef"
        rig._take(rig.ctl.handle(b"0000beef:set_speed:0." + b"0" * 100 + b"1", "a", 0.0))
    ack = rig.ack("a", mid)
    assert ack.status is Status.ERROR and ack.error_code == ErrorCode.ILLEGAL_VALUE
    assert rig.ctl.pending_speed_pct is None


def test_set_speed_at_the_minimum_and_maximum_is_accepted(rig):
    assert rig.ack("a", rig.send("a", "set_speed", 1, now=0.0)).status is Status.DONE
    assert rig.ack("a", rig.send("a", "set_speed", 100, now=0.0)).status is Status.DONE


@pytest.mark.parametrize("data", [
    b"0000a001:set_speed:1e308", b"0000a001:set_speed:1_0", b"0000a001:set_speed:inf", b"0000a001:set_speed:nan",
    b"0000a001:set_speed:\t10", b"0000a001:set_speed: 10", b"0000a001:set_speed:10 ", b"0000a001:set_speed:1\x0b0",
    b"0000a001:set_speed:10\x00", b"0000a001:set_speed:0x10", b"0000a001:set_speed:+-1", b"0000a001:set_speed:1e2",
    b"0000a001:here\x01", b"0000a001\t:here", b"0000a001:move_joints:0,-90,180,0,90,\x7f0",
])
def test_bad_numbers_and_control_characters_answer_error_acks(rig, data):
    out = rig.ctl.handle(data, "a", 0.0)
    assert len(out) == 1 and out[0].ack.status is Status.ERROR
    assert out[0].ack.error_code in (ErrorCode.ILLEGAL_VALUE, ErrorCode.MALFORMED_MESSAGE)
    # The connection stays usable.
    assert rig.ack("a", rig.send("a", "here", now=0.0)).status is Status.DONE


@pytest.mark.parametrize("skill,args", [
    ("move_to", (480, 0, 500, 1e20, 180, 0)),
    ("move_to", (480, 0, 500, 0, 180, 721)),
    ("move_rel_world", (0, 0, 0, 0, 0, 1e20)),
    ("move_rel_tool", (0, 0, 0, 1e20, 0, 0)),
    ("move_rel_joints", (0, 0, 0, 0, 0, 1e20)),
    ("move_joints", (0, -90, 180, 0, 90, 1e20)),
    ("move_to", (1e20, 0, 500, 0, 180, 0)),
    ("move_rel_world", (5e7, 0, 0, 0, 0, 0)),
    ("move_to", (480, 0, 500, 0, 180, 360.5)),
])
def test_absurd_rotations_and_magnitudes_are_refused_before_motion(rig, skill, args):
    text = f"0000c001:{skill}:" + ",".join("%.3f" % a for a in args)
    out = rig.ctl.handle(text.encode(), "a", 0.0)
    assert len(out) == 1 and out[0].ack.status is Status.ERROR, out
    assert out[0].ack.error_code == ErrorCode.ILLEGAL_VALUE
    assert not rig.ctl.trajectory.in_motion(0.0) and rig.ctl.joints_at(5.0) == HOME


def test_the_reserved_id_is_refused(rig):
    out = rig.ctl.handle(b"00000000:move_joints:30,-90,180,0,90,0", "a", 0.0)
    assert len(out) == 1 and out[0].ack.status is Status.ERROR and out[0].ack.id == NO_ID
    assert out[0].ack.error_code == ErrorCode.MALFORMED_MESSAGE and "reserved" in out[0].ack.error_message
    assert rig.ctl.joints_at(5.0) == HOME


def test_a_second_message_with_an_id_still_pending_answers_an_error_and_nothing_hangs(rig):
    rig.send("a", "move_joints", 60, -90, 180, 0, 90, 0, now=0.0)
    rig.send("a", "break", now=0.0, id="0000dddd")
    out = rig.ctl.handle(b"0000dddd:move_joints:-60,-90,180,0,90,0", "a", 0.01)
    assert [(o.ack.id, o.ack.status, o.ack.error_code) for o in out] == [
        ("0000dddd", Status.ERROR, ErrorCode.MALFORMED_MESSAGE)]
    assert "pending" in out[0].ack.error_message
    # Another connection may use the same ID; the first break still completes; the duplicate never ran.
    assert rig.ack("b", rig.send("b", "break", now=0.02, id="0000dddd")) is None
    rig.run_until_idle()
    assert rig.ack("a", "0000dddd").status is Status.DONE and rig.ack("b", "0000dddd").status is Status.DONE
    assert rig.ctl.joints_at(20.0)[0] == pytest.approx(60.0)
    # Once answered, the ID is free again.
    assert rig.ack("a", rig.send("a", "here", now=20.0, id="0000dddd")).status is Status.DONE


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=40))
def test_parse_command_accepts_only_the_grammar(tail):
    """Whatever follows a valid head, a parsed argument is a finite number written in the %.3f grammar."""
    line = b"0000abcd:move_to:" + tail
    try:
        msg = parse_command(line)
    except RemoteProtocolError as exc:
        assert exc.code in (ErrorCode.ILLEGAL_VALUE, ErrorCode.MALFORMED_MESSAGE)
        return
    for tok, v in zip(tail.split(b","), msg.args, strict=True):
        assert math.isfinite(v)
        assert tok and all(c in b"+-.0123456789" for c in tok), tok


# -- 9. read-only queries from an idle connection are answered at once ------------------------------------------

def test_here_from_an_idle_connection_is_answered_at_once_while_another_client_moves(rig):
    rig.send("a", "move_joints", 100, -90, 180, 0, 90, 0, now=0.0)
    brk = rig.send("a", "break", now=0.0)
    h = rig.send("b", "here", now=0.2)
    hi = rig.send("c", "hello", now=0.2)
    here = rig.ack("b", h)
    assert here is not None and here.status is Status.DONE and here.t_done_s == pytest.approx(0.2)
    assert here.extra[0] == ",".join("%.3f" % v for v in rig.ctl.joints_at(0.2))  # the pose now, mid-motion
    assert rig.ack("c", hi).status is Status.DONE
    assert rig.ack("a", brk) is None


def test_here_behind_the_same_connections_queue_keeps_its_order(rig):
    rig.send("a", "move_joints", 100, -90, 180, 0, 90, 0, now=0.0)
    brk = rig.send("a", "break", now=0.0)
    h = rig.send("a", "here", now=0.2)
    assert rig.ack("a", h) is None  # a's own break comes first
    rig.run_until_idle()
    assert rig.ack("a", h).t_done_s == pytest.approx(rig.ack("a", brk).t_done_s)
    assert rig.ack("a", h).extra[0] == "100.000,-90.000,180.000,0.000,90.000,0.000"


# -- F6. forward processing is one motion deep -------------------------------------------------------------------

def test_second_move_acks_only_when_the_first_has_nearly_completed(rig):
    a = rig.send("a", "move_joints", 40, -90, 180, 0, 90, 0, now=0.0)
    b = rig.send("a", "move_joints", 80, -90, 180, 0, 90, 0, now=0.0)
    brk = rig.send("a", "break", now=0.0)
    assert rig.ack("a", a).t_done_s == 0.0
    assert rig.ack("a", b) is None  # waits for motion a
    rig.run_until_idle()
    d = j1_duration(40)
    assert rig.ack("a", b).t_done_s == pytest.approx(d - 0.1)  # as a begins to decelerate (blend)
    assert rig.ack("a", brk).t_done_s == pytest.approx(2 * d - 0.1)
    assert rig.ctl.joints_at(rig.ack("a", brk).t_done_s)[0] == pytest.approx(80.0)
