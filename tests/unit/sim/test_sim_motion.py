"""Motion timing: synchronised trapezoids, speed scaling, blending, stopping, time scale (pure, no clock)."""

from itertools import pairwise

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.robots.viper_s850 import HOME_JOINTS_DEG, MAX_JOINT_SPEED_DEG_S
from aioadept.sim.motion import MotionLimits, Segment, Trajectory, plan_duration

HOME = HOME_JOINTS_DEG


def test_long_move_duration_is_distance_over_speed_plus_one_ramp():
    # J1 by 200 deg at 250 deg/s: 0.8 s cruise-equivalent + 0.1 s ramp.
    d, ramp = plan_duration([200, 0, 0, 0, 0, 0], 1.0)
    assert d == pytest.approx(0.9) and ramp == pytest.approx(0.1)


def test_short_move_is_triangular():
    # 1 deg on J1: a = 2500 deg/s^2, T = 2 sqrt(d / a) = 0.04 s, ramp T/2.
    d, ramp = plan_duration([1, 0, 0, 0, 0, 0], 1.0)
    assert d == pytest.approx(0.04) and ramp == pytest.approx(0.02)


def test_half_speed_doubles_cruise_time_of_a_long_move():
    d100, r100 = plan_duration([300, 100, 0, 0, 0, 0], 1.0)
    d50, r50 = plan_duration([300, 100, 0, 0, 0, 0], 0.5)
    assert r100 == r50 == pytest.approx(0.1)  # SCALE.ACCEL: the ramp time does not change
    # T = distance / speed + ramp: the distance/speed part doubles exactly, the cruise (T - 2 ramp) roughly.
    assert (d50 - r50) == pytest.approx(2 * (d100 - r100))
    assert 2.0 < (d50 - 2 * r50) / (d100 - 2 * r100) < 2.15


def test_slowest_joint_sets_the_duration():
    # J6 at 600 deg/s covering 300 deg is faster than J1 covering 200 deg at 250 deg/s.
    assert plan_duration([200, 0, 0, 0, 0, 300], 1.0)[0] == pytest.approx(0.9)
    assert plan_duration([0, 0, 0, 0, 0, 600], 1.0)[0] == pytest.approx(1.1)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-200, 200), min_size=6, max_size=6), st.integers(1, 100))
def test_profile_respects_speed_limits_and_arrives_together(delta, speed):
    traj = Trajectory(HOME)
    target = tuple(np.add(HOME, delta))
    seg = traj.add(target, 0.0, speed_pct=speed)
    vmax = np.array(MAX_JOINT_SPEED_DEG_S) * speed / 100
    for t in np.linspace(0, seg.t_end_s, 50):
        assert np.all(np.abs(traj.velocity(float(t))) <= vmax * (1 + 1e-9) + 1e-9)
    assert traj.position(seg.t_end_s) == pytest.approx(target, abs=1e-9)
    assert traj.position(seg.t_end_s + 5) == pytest.approx(target, abs=1e-9)
    if np.any(delta):
        # Every moving joint is still short of its target just before the end: they arrive together.
        before = np.array(traj.position(seg.t_end_s * 0.99))
        moving = np.abs(delta) > 1e-3
        assert np.all(np.abs(before - target)[moving] > 0)


def test_position_is_continuous_and_monotone_along_a_segment():
    seg = Segment(HOME, tuple(np.add(HOME, [90, 0, 0, 0, 0, 0])), 1.0, 0.46, 0.1, 100)
    ps = [seg.progress(t) for t in np.linspace(0.9, 1.6, 701)]
    assert ps[0] == 0 and ps[-1] == 1
    assert all(b >= a for a, b in pairwise(ps))
    assert max(abs(b - a) for a, b in pairwise(ps)) < 0.01


def test_blended_motion_starts_as_the_previous_decelerates():
    traj = Trajectory(HOME)
    a = traj.add(np.add(HOME, [100, 0, 0, 0, 0, 0]), 0.0, speed_pct=100)
    b = traj.add(np.add(HOME, [100, 0, 0, 0, 0, 0]) + [0, 0, 0, 0, 0, 0] + [50, 0, 0, 0, 0, 0], 0.2, speed_pct=100)
    assert b.t0_s == pytest.approx(a.t_end_s - 0.1)
    assert traj.pending_start_s(0.2) == pytest.approx(b.t0_s)
    assert traj.pending_start_s(b.t0_s) is None
    # No stop between them: J1 keeps its full speed through the blend.
    assert traj.velocity(a.t_end_s - 0.05)[0] == pytest.approx(250.0)
    assert traj.position(b.t_end_s)[0] == pytest.approx(150.0)
    assert traj.t_rest_s == pytest.approx(b.t_end_s)


def test_ready_is_when_the_last_motion_begins_to_decelerate_or_a_stop_is_at_rest():
    traj = Trajectory(HOME)
    assert traj.ready_s() is None
    a = traj.add(np.add(HOME, [100, 0, 0, 0, 0, 0]), 0.0, speed_pct=100)
    assert traj.ready_s() == pytest.approx(a.t_end_s - a.ramp_s)
    # Issued at ready_s, the next motion starts at once (the blend point): its ack can say "started".
    b = traj.add(np.add(HOME, [150, 0, 0, 0, 0, 0]), traj.ready_s(), speed_pct=100)
    assert b.t0_s == pytest.approx(a.t_end_s - a.ramp_s)
    t_rest = traj.stop(b.t0_s + 0.05)
    assert traj.ready_s() == pytest.approx(t_rest)


def test_motion_after_rest_starts_when_issued():
    traj = Trajectory(HOME)
    a = traj.add(np.add(HOME, [10, 0, 0, 0, 0, 0]), 0.0, speed_pct=100)
    b = traj.add(HOME, a.t_end_s + 1.0, speed_pct=100)
    assert b.t0_s == pytest.approx(a.t_end_s + 1.0)
    assert traj.position(b.t_end_s) == pytest.approx(HOME)


def test_stop_decelerates_to_rest_short_of_the_target():
    traj = Trajectory(HOME)
    seg = traj.add(np.add(HOME, [200, 0, 0, 0, 0, 0]), 0.0, speed_pct=100)
    t_stop = 0.4
    p0 = traj.position(t_stop)[0]
    t_rest = traj.stop(t_stop)
    assert t_rest == pytest.approx(t_stop + 0.1)  # 250 deg/s at 2500 deg/s^2
    # Constant deceleration from 250 deg/s over 0.1 s covers 12.5 deg.
    assert traj.position(t_rest)[0] == pytest.approx(p0 + 12.5)
    assert traj.position(t_rest + 1)[0] == pytest.approx(p0 + 12.5)
    assert traj.position(t_rest)[0] < seg.end_deg[0]
    assert not traj.in_motion(t_rest) and traj.in_motion(t_stop + 0.05)
    assert traj.end_deg == pytest.approx(traj.position(t_rest))


def test_stop_at_rest_is_immediate():
    traj = Trajectory(HOME)
    assert traj.stop(3.0) == 3.0 and traj.position(3.0) == pytest.approx(HOME)


def test_time_scale_divides_durations_and_instant_removes_them():
    fast = Trajectory(HOME, time_scale=10).add(np.add(HOME, [200, 0, 0, 0, 0, 0]), 0.0, speed_pct=100)
    assert fast.duration_s == pytest.approx(0.09)
    inst = Trajectory(HOME, instant=True)
    seg = inst.add(np.add(HOME, [200, 0, 0, 0, 0, 0]), 2.0, speed_pct=100)
    assert seg.t_end_s == 2.0 and inst.position(2.0)[0] == pytest.approx(200)


def test_invalid_options_are_rejected():
    with pytest.raises(ValueError):
        plan_duration([1] * 6, 0.0)
    with pytest.raises(ValueError):
        Trajectory(HOME, time_scale=0)
    with pytest.raises(ValueError):
        MotionLimits(ramp_s=0)
