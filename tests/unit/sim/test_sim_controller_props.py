"""Properties of the controller under random traffic from two clients: one ack per command, time order, limits."""

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.protocol import Status, encode_ack
from aioadept.robots import viper_s850 as kin
from aioadept.sim.controller import Controller

LIM = kin.VIPER_S850_LIMITS

joints = st.tuples(*(st.floats(lo - 20, hi + 20) for lo, hi in zip(LIM.min_deg, LIM.max_deg, strict=True)))
small = st.tuples(*(st.floats(-60, 60) for _ in range(6)))

command = st.one_of(
    st.tuples(st.just("move_joints"), joints),
    st.tuples(st.just("move_rel_joints"), small),
    st.tuples(st.just("move_rel_tool"), small),
    st.tuples(st.just("move_rel_world"), small),
    st.tuples(st.just("move_to"), st.tuples(st.floats(-900, 900), st.floats(-900, 900), st.floats(-300, 1200),
                                             st.floats(-180, 180), st.floats(0, 180), st.floats(-180, 180))),
    st.tuples(st.just("set_speed"), st.tuples(st.integers(-5, 110))),
    st.tuples(st.sampled_from(["break", "here", "hello", "stop", "enable_air", "fly"]), st.just(())),
    st.tuples(st.just("garbage"), st.just(())),
)
traffic = st.lists(st.tuples(st.sampled_from(["a", "b"]), command, st.floats(0, 0.4)), min_size=1, max_size=30)


def line(mid: str, skill: str, args) -> bytes:
    if skill == "garbage":
        return b"\x00not a line"
    return (f"{mid}:{skill}" + (":" + ",".join("%.3f" % a if isinstance(a, float) else "%d" % a for a in args)
                                if args else "")).encode()


@settings(max_examples=150, deadline=None)
@given(traffic, st.booleans(), st.sampled_from([1.0, 7.0]))
def test_every_command_gets_exactly_one_ack_in_time_order_and_limits_hold(ops, instant, scale):
    ctl = Controller(instant=instant, time_scale=scale)
    ctl.connect("a")
    ctl.connect("b")
    out = []
    sent = {"a": [], "b": []}
    now = 0.0
    for i, (conn, (skill, args), dt) in enumerate(ops):
        now += dt
        mid = "%08x" % (i + 1)
        if skill != "garbage":
            sent[conn].append(mid)
        out += ctl.handle(line(mid, skill, args), conn, now)
        # Joint limits hold wherever the arm is at any event.
        assert not LIM.violations(ctl.joints_at(now), tol_deg=1e-6)
    for _ in range(1000):
        wake = ctl.next_wake_s()
        if wake is None:
            break
        out += ctl.step(wake)
        assert not LIM.violations(ctl.joints_at(wake), tol_deg=1e-6)
    assert ctl.next_wake_s() is None and ctl.queued() == 0
    for conn in ("a", "b"):
        acks = [o.ack for o in out if o.conn == conn]
        routed = [a.id for a in acks if a.id != "00000000"]
        assert sorted(routed) == sorted(sent[conn])  # exactly one ack per command, to its sender
        t_done = [a.t_done_s for a in acks]
        assert t_done == sorted(t_done)
        for a in acks:
            assert a.t_start_s <= a.t_done_s + 1e-12 and math.isfinite(a.pose.x)
            encode_ack(a)  # every ack is encodable
            if a.status is Status.ERROR:
                assert a.error_code is not None and a.error_code < 0
    # Motions without a break end too, within the limits.
    t_end = max(ctl.now_s, ctl.trajectory.t_rest_s) + 1e-9
    assert not ctl.trajectory.in_motion(t_end) and not LIM.violations(ctl.joints_at(t_end), tol_deg=1e-6)
