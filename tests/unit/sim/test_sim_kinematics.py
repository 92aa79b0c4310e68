"""Viper s850 kinematics: home pose, FK/IK round trips, configurations, joint limits, reach, the paper's sequence."""

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from aioadept.errors import RobotError
from aioadept.geometry import Pose, poses_close, rel_tool
from aioadept.protocol import ErrorCode
from aioadept.robots import viper_s850 as viper
from aioadept.robots import viper_s850 as kin
from aioadept.robots.viper_s850 import HOME_JOINTS_DEG, VIPER_S850_LIMITS, configuration, forward, inverse

LIM = VIPER_S850_LIMITS


def joint_vectors(margin: float = 1.0):
    return st.tuples(*(st.floats(lo + margin, hi - margin, allow_nan=False)
                       for lo, hi in zip(LIM.min_deg, LIM.max_deg, strict=True)))


def test_home_is_tool_down_at_the_real_acks_pose():
    p = forward(HOME_JOINTS_DEG)
    # The real controller answered 480.014,-0.038,709.975,0.000,179.995,0.004 at home (docs/protocol.md, its examples).
    assert (p.x, p.y, p.z) == pytest.approx((480.0, 0.0, 710.0), abs=1e-9)
    assert poses_close(p, Pose(480, 0, 710, 0, 180, 0), tol_mm=1e-9, tol_deg=1e-9)
    np.testing.assert_allclose(p.to_matrix()[:3, 2], [0, 0, -1], atol=1e-12)  # tool z points down


def test_forward_matches_visp_closed_form():
    # ViSP vpViper::get_fMe, translation, written out independently of our factorisation.
    q = np.radians([20.0, -70.0, 150.0, 30.0, 60.0, -45.0])
    c1, s1 = math.cos(q[0]), math.sin(q[0])
    c2, s2 = math.cos(q[1]), math.sin(q[1])
    c23, s23 = math.cos(q[1] + q[2]), math.sin(q[1] + q[2])
    c4, s4, c5, s5 = math.cos(q[3]), math.sin(q[3]), math.cos(q[4]), math.sin(q[4])
    a1, d1, a2, a3, d4, d6 = 75, 335, 365, 90, 405, 80
    x = c1 * (c23 * (c4 * s5 * d6 - a3) + s23 * (c5 * d6 + d4) + a1 + a2 * c2) - s1 * s4 * s5 * d6
    y = s1 * (c23 * (c4 * s5 * d6 - a3) + s23 * (c5 * d6 + d4) + a1 + a2 * c2) + c1 * s4 * s5 * d6
    z = s23 * (a3 - c4 * s5 * d6) + c23 * (c5 * d6 + d4) - a2 * s2 + d1
    r22 = -s23 * c4 * s5 + c23 * c5
    m = kin.flange_matrix(np.degrees(q))
    np.testing.assert_allclose(m[:3, 3], [x, y, z], atol=1e-9)
    assert m[2, 2] == pytest.approx(r22)


def test_reach_matches_datasheet():
    assert kin.REACH_MM == pytest.approx(854.9, abs=0.1)


@settings(max_examples=300, deadline=None)
@given(joint_vectors(), st.lists(st.floats(-3, 3), min_size=6, max_size=6))
@example((0.0, 0.0, 101.0, 0.0, 3.0, 0.0), [0.0, -1.0, 1.0, 0.0, -2.0, 0.0])  # elbow near stretched: either branch
def test_fk_ik_round_trip_from_a_nearby_start(q, nudge):
    conf = configuration(q)
    assume(0 not in (conf.shoulder, conf.elbow, conf.wrist))
    assume(abs(math.sin(math.radians(q[4]))) > 0.05)  # away from the wrist singularity
    start = [a + d for a, d in zip(q, nudge, strict=True)]
    assume(not LIM.violations(start) and configuration(start) == conf)
    sol = inverse(forward(q), start)
    assert poses_close(forward(sol), forward(q), tol_mm=1e-6, tol_deg=1e-6)
    # The configuration of the start, except for a flag within its band of a singularity (either choice is allowed
    # there, so the arm passes through instead of flipping), and the solution nearest the start: never farther from
    # it than q, which is one of the solutions.
    assert viper._matches(configuration(sol), viper._free_configuration(start))
    def dist(a):  # the joint-space distance inverse() minimises (sum of the joints' moves)
        return math.fsum(abs(x - y) for x, y in zip(a, start, strict=True))
    assert dist(sol) <= dist(q) + 1e-6
    if viper._free_configuration(start) == conf:  # no flag free: q is the one nearest solution
        assert sol == pytest.approx(q, abs=1e-6)


@settings(max_examples=100, deadline=None)
@given(joint_vectors(), st.sampled_from([Pose(0, 0, 120), Pose(10, -5, 150, 0, 0, 30)]))
def test_fk_ik_round_trip_with_a_tool(q, tool):
    assume(abs(math.sin(math.radians(q[4]))) > 0.05)
    assume(0 not in (configuration(q).shoulder, configuration(q).elbow))
    target = forward(q, tool)
    sol = inverse(target, q, tool)
    assert poses_close(forward(sol, tool), target, tol_mm=1e-6, tol_deg=1e-6)
    assert sol == pytest.approx(q, abs=1e-6)


def test_tool_offsets_along_the_flange_z():
    p = forward(HOME_JOINTS_DEG, Pose(0, 0, 100))
    assert (p.x, p.y, p.z) == pytest.approx((480, 0, 610))


def test_inverse_keeps_the_elbow_configuration():
    q = [10.0, -40.0, 120.0, 20.0, 50.0, 10.0]
    target = forward(q)
    sols = [s for s, _ in kin._solutions_rad(target.to_matrix(), 0.0)]
    assert len(sols) >= 4  # shoulder x elbow x wrist branches exist for this pose
    assert configuration(inverse(target, q)) == configuration(q)


def test_j6_wrap_takes_the_short_way():
    q = [0.0, -90.0, 180.0, 0.0, 90.0, 350.0]
    target = forward([0.0, -90.0, 180.0, 0.0, 90.0, -5.0])  # same as 355
    assert inverse(target, q)[5] == pytest.approx(355.0)
    # From -350 the equivalent -365 is beyond the limit, so the nearest allowed one is -5: J6 would unwind 345 deg
    # for a 15 deg turn of the tool. Refused by default (jump limit); without the jump limit, -5.
    with pytest.raises(RobotError) as info:
        inverse(target, [0.0, -90.0, 180.0, 0.0, 90.0, -350.0])
    assert info.value.code == ErrorCode.JOINT_JUMP and "J6" in info.value.message
    assert inverse(target, [0.0, -90.0, 180.0, 0.0, 90.0, -350.0], jump=None)[5] == pytest.approx(-5.0)


def test_j4_wrap_stays_within_limits():
    q = [0.0, -90.0, 180.0, 185.0, 60.0, 0.0]
    sol = inverse(forward(q), q)
    assert sol[3] == pytest.approx(185.0)
    # -170 is 190 (+360), 20 deg away from 170 and within the J4 limit of 190: take it, not the 340 deg way.
    far = [0.0, -90.0, 180.0, 170.0, 60.0, 0.0]
    assert inverse(forward([0.0, -90.0, 180.0, -170.0, 60.0, 0.0]), far)[3] == pytest.approx(190.0)
    # From 150 the same target at 190 is 40 deg away and -170 is 320: still 190.
    assert inverse(forward([0.0, -90.0, 180.0, -170.0, 60.0, 0.0]), [0.0, -90.0, 180.0, 150.0, 60.0, 0.0])[3] \
        == pytest.approx(190.0)


def test_out_of_reach_raises_typed_error():
    with pytest.raises(RobotError) as info:
        inverse(Pose(2000, 0, 500, 0, 180, 0), HOME_JOINTS_DEG)
    assert info.value.code == ErrorCode.OUT_OF_REACH


def test_target_beyond_j1_limit_raises_joint_limit():
    q = [165.0, -90.0, 180.0, 0.0, 90.0, 0.0]
    target = forward([178.0, -90.0, 180.0, 0.0, 90.0, 0.0])
    with pytest.raises(RobotError) as info:
        inverse(target, q)
    assert info.value.code == ErrorCode.JOINT_LIMIT
    assert "J1" in info.value.message


@pytest.mark.parametrize("joint,value", [(0, 171), (1, -191), (1, 46), (2, -30), (2, 257), (3, 191), (4, -121),
                                         (5, 361)])
def test_joint_limits_are_enforced(joint, value):
    q = list(HOME_JOINTS_DEG)
    q[joint] = value
    assert LIM.violations(q) == [joint]
    with pytest.raises(RobotError) as info:
        kin.check_joint_path(HOME_JOINTS_DEG, q)
    assert info.value.code == ErrorCode.JOINT_LIMIT and f"J{joint + 1}" in info.value.message
    q[joint] = value - math.copysign(1.0, value) * 1.0
    kin.check_joint_path(HOME_JOINTS_DEG, q)  # just inside: fine


def test_paper_init_move_sequence_is_reachable_and_within_limits():
    q = list(HOME_JOINTS_DEG)
    LIM.check(q)
    q = [a + d for a, d in zip(q, [-90, 60, 30, -90, 0, 0], strict=True)]
    kin.check_joint_path(HOME_JOINTS_DEG, q)
    approach = forward(q)
    # The pose of the paper's move_to example message.
    assert poses_close(approach, Pose(-80, -481.1, 112.5, 180, 90, 180), tol_mm=0.01, tol_deg=1e-6)
    target = rel_tool(approach, (40, -25, 185, 0, 0, 0))
    q2 = inverse(target, q)
    LIM.check(q2)
    assert configuration(q2) == configuration(q)
    assert poses_close(forward(q2), target, tol_mm=1e-6, tol_deg=1e-6)
    q3 = list(q2)
    q3[5] += 1.5
    LIM.check(q3)
    final = forward(q3)
    assert (final.x, final.y, final.z) == pytest.approx((target.x, target.y, target.z), abs=1e-6)


def test_wrist_singularity_keeps_j4_and_puts_the_rest_in_j6():
    target = forward([0.0, -90.0, 180.0, 30.0, 0.0, 20.0])  # j5 = 0: only j4 + j6 = 50 is defined
    sol = inverse(target, [0.0, -90.0, 180.0, 10.0, 30.0, 0.0])
    assert sol[4] == pytest.approx(0.0, abs=1e-9)
    assert sol[3] == pytest.approx(10.0) and sol[5] == pytest.approx(40.0)
    # Reachable from the flipped wrist as well (the singular solution belongs to both).
    sol = inverse(target, [0.0, -90.0, 180.0, 10.0, -30.0, 0.0])
    assert poses_close(forward(sol), target, tol_mm=1e-6, tol_deg=1e-6)
