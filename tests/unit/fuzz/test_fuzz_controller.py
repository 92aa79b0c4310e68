"""Fuzz properties of the simulated controller fed arbitrary lines (pure, fake clock).

Every framed line gets exactly one ack: its own ID when the parser can recover one (``00000000`` otherwise), and an
``error`` ack whenever the parser rejects it. Nothing raises. The state stays consistent: a refused line leaves
the arm where it was, the joints stay inside their limits, and nothing is left queued or running once the
controller has been stepped past every motion.
"""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.errors import RemoteProtocolError
from aioadept.protocol import MAX_LINE, NO_ID, LineFramer, Oversize, Status, parse_command, recover_id
from aioadept.sim.controller import Controller

from fuzz_strategies import lines

# Valid motion traffic mixed in, so that the garbage arrives while the arm is somewhere else than home.
valid = st.one_of(
    st.tuples(st.floats(-30, 30), st.floats(-110, -70), st.floats(150, 200), st.floats(-20, 20),
              st.floats(50, 110), st.floats(-60, 60)).map(
        lambda j: ("0000beef:move_joints:" + ",".join("%.3f" % v for v in j)).encode()),
    st.sampled_from([b"0000bee1:break", b"0000bee2:here", b"0000bee3:set_speed:50", b"0000bee4:enable_air",
                     b"0000bee5:move_rel_tool:0,0,5,0,0,0", b"0000bee6:move_joints:0,-90,180,0,90,400",
                     b"0000bee7:move_to:2000,0,0,0,180,0", b"0000bee8:stop"]),
)


def expected(item: bytes | Oversize) -> tuple[str, bool]:
    if isinstance(item, Oversize):
        return recover_id(item.head) or NO_ID, True
    try:
        return parse_command(item).id, False
    except RemoteProtocolError as exc:
        return exc.id or NO_ID, True


@settings(max_examples=50, deadline=None)
@given(traffic=st.lists(st.one_of(lines, valid), min_size=1, max_size=25), instant=st.booleans(),
       delims=st.lists(st.sampled_from([b"\r\n", b"\n"]), min_size=25, max_size=25))
def test_every_line_is_answered_once_and_state_stays_consistent(traffic, instant, delims):
    ctl = Controller(instant=instant, time_scale=50.0)
    ctl.connect("c")
    framer = LineFramer(MAX_LINE)
    now = 0.0
    for raw, delim in zip(traffic, delims, strict=False):  # delims: one per line, 25 drawn
        for item in framer.feed(raw + delim):
            want_id, must_err = expected(item)
            joints_before = ctl.joints_at(now)
            now += 0.01
            out = ctl.handle(item, "c", now)
            # Step the fake clock until nothing is due: every motion done, every waiting skill answered.
            while (wake := ctl.next_wake_s()) is not None:
                now = max(now, wake)
                out += ctl.step(now)
            now = max(now, ctl.trajectory.t_rest_s)  # a move acks when it starts; let it finish
            out += ctl.step(now)
            assert len(out) == 1, (item, out)
            ack = out[0].ack
            assert out[0].conn == "c" and ack.id == want_id
            if must_err:
                assert ack.status is Status.ERROR
            if ack.status is Status.ERROR:
                # Refused before motion: the arm did not move because of it.
                assert ctl.joints_at(now) == joints_before
                assert ack.error_code is not None and ack.error_code < 0
            ctl.joint_limits.check(ctl.joints_at(now))  # raises if a limit was crossed
            assert ctl.queued() == 0 and not ctl.busy
    # Still serving after all that: a valid here is answered done with the current pose.
    out = ctl.handle(b"0000f1a1:here", "c", now + 1)
    assert [o.ack.status for o in out] == [Status.DONE] and out[0].ack.pose == ctl.here_at(now + 1)


@settings(max_examples=25, deadline=None)
@given(garbage=st.lists(lines, max_size=10))
def test_garbage_from_one_client_does_not_reach_another(garbage):
    ctl = Controller(instant=True)
    ctl.connect("good")
    ctl.connect("bad")
    framer = LineFramer(MAX_LINE)
    acks_good = ctl.handle(b"0000aaaa:move_joints:10,-90,180,0,90,0", "good", 0.0)
    for raw in garbage:
        for item in framer.feed(raw + b"\r\n"):
            out = ctl.handle(item, "bad", 0.5)
            assert all(o.conn == "bad" for o in out)
    acks_good += ctl.handle(b"0000aaab:break", "good", 1.0) + ctl.step(10.0)
    assert [(o.conn, o.ack.id) for o in acks_good if o.conn == "good"][-1] == ("good", "0000aaab")
