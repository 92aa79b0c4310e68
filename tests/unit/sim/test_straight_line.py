"""Straight-line motion in the one robot model (aioadept.sim.line, motion.LineSegment, Controller.move_line):
the tool stays on the line, orientation follows the slerp, V+'s straight-line speed, refusals before moving, a
stop along the line, and the skills' acks. No sockets: time is passed in."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aioadept.errors import RobotError
from aioadept.geometry import Pose, pose_error, poses_close
from aioadept.protocol import ErrorCode, Status
from aioadept.robots import viper_s850 as kin
from aioadept.sim.controller import Controller
from aioadept.sim.line import CartesianLimits, line_pose_matrix

A = Pose(400.0, -150.0, 400.0, 0.0, 180.0, 0.0)
B = Pose(400.0, 150.0, 400.0, 0.0, 180.0, 30.0)


def at(ctl: Controller, pose: Pose) -> Controller:
    """Put the arm at rest at ``pose`` (a joint move run to the end)."""
    for wake in ctl.move_pose(pose):
        ctl.now_s = wake
    ctl.now_s = ctl.trajectory.t_rest_s + 1.0
    return ctl


def off_line(p: Pose, a: Pose = A, b: Pose = B) -> tuple[float, float]:
    d = b.position_mm - a.position_mm
    f = float(np.clip((p.position_mm - a.position_mm) @ d / (d @ d), 0.0, 1.0))
    return float(np.linalg.norm(p.position_mm - (a.position_mm + f * d))), f


def run_line(ctl: Controller, target: Pose, speed_pct: float = 100.0):
    path = ctl.plan_line(target)
    return ctl.trajectory.add_line(path, ctl.now_s, speed_pct=speed_pct)


def test_the_tool_stays_on_the_line_and_turns_on_the_slerp():
    ctl = at(Controller(), A)
    seg = run_line(ctl, B)
    worst_mm = worst_deg = 0.0
    for t in np.linspace(seg.t0_s, seg.t_end_s, 1001):
        p = kin.forward(ctl.trajectory.position(float(t)))
        dist, f = off_line(p)
        want = Pose.from_matrix(line_pose_matrix(A.to_matrix(), B.to_matrix(), f))
        worst_mm = max(worst_mm, dist)
        worst_deg = max(worst_deg, pose_error(p, want)[1])
    assert worst_mm < 0.01, "micrometres, far inside the 0.5 mm the issue asks for"
    assert worst_deg < 0.01
    assert poses_close(kin.forward(ctl.trajectory.position(seg.t_end_s)), B, tol_mm=1e-6, tol_deg=1e-6)


def test_a_joint_move_between_the_same_ends_leaves_the_line():
    # The check above can fail: the same measurement of a joint-interpolated move sees it bow away.
    ctl = at(Controller(), A)
    for wake in ctl.move_pose(B):
        ctl.now_s = wake
    seg = ctl.trajectory._segments[-1]
    worst = max(off_line(kin.forward(ctl.trajectory.position(float(t))))[0]
                for t in np.linspace(seg.t0_s, seg.t_end_s, 201))
    assert worst > 2.0


@pytest.mark.parametrize("speed_pct", [50.0, 10.0])
def test_straight_line_speed_is_a_fraction_of_the_cartesian_speed(speed_pct):
    ctl = at(Controller(), A)
    seg = run_line(ctl, Pose(400.0, 150.0, 400.0, 0.0, 180.0, 0.0), speed_pct)
    v = 2000.0 * speed_pct / 100.0
    # 300 mm at v mm/s plus one ramp (0.1 s); no joint needs more than its maximum on this line at these speeds.
    assert seg.duration_s == pytest.approx(300.0 / v + 0.1, rel=0.01)
    mid = (seg.t0_s + seg.t_end_s) / 2
    p0 = kin.forward(ctl.trajectory.position(mid - 0.005)).position_mm
    p1 = kin.forward(ctl.trajectory.position(mid + 0.005)).position_mm
    assert np.linalg.norm(p1 - p0) / 0.01 == pytest.approx(v, rel=0.05), "cruise at the tool speed asked for"


def test_a_joint_at_its_maximum_speed_slows_the_whole_line_down():
    # At 100 % (2000 mm/s) J1 would need about 290 deg/s where the line passes closest to the base (250 max).
    ctl = at(Controller(), A)
    seg = run_line(ctl, Pose(400.0, 150.0, 400.0, 0.0, 180.0, 0.0), 100.0)
    assert seg.duration_s > 300.0 / 2000.0 + 0.1 + 0.01
    ts = np.linspace(seg.t0_s, seg.t_end_s, 400)
    j1 = [ctl.trajectory.velocity(float(t))[0] for t in ts]
    assert max(abs(v) for v in j1) <= 250.0 * 1.01


def test_a_slower_cartesian_limit_makes_the_same_line_slower():
    fast = run_line(at(Controller(), A), B)
    slow = run_line(at(Controller(cartesian_limits=CartesianLimits(max_speed_mm_s=500.0)), A), B)
    assert slow.duration_s > 2 * fast.duration_s


def test_a_line_near_the_wrist_singularity_is_refused_before_moving():
    a = Pose(560.0, -50.0, 785.0, 0.0, 90.0, 0.0)
    ctl = at(Controller(), a)
    before = ctl.trajectory.end_deg
    with pytest.raises(RobotError) as err:
        list(ctl.move_line(Pose(560.0, 50.0, 785.0, 0.0, 90.0, 0.0)))
    assert err.value.code == ErrorCode.JOINT_JUMP
    assert "singularity" in err.value.message and err.value.message.startswith("line ")
    assert ctl.trajectory.end_deg == before and not ctl.trajectory.in_motion(ctl.now_s)


def test_a_line_past_a_joint_limit_part_way_is_refused_though_both_ends_are_reachable():
    r, ang = 500.0, math.radians(160.0)
    start = Pose(r * math.cos(ang), r * math.sin(ang), 400.0, 0.0, 180.0, 0.0)
    end = Pose(r * math.cos(ang), -r * math.sin(ang), 400.0, 0.0, 180.0, 0.0)
    ctl = at(Controller(), start)
    with pytest.raises(RobotError) as err:
        ctl.plan_line(end)
    assert err.value.code == ErrorCode.JOINT_LIMIT and "J1" in err.value.message
    kin.inverse(end, ctl.trajectory.end_deg, jump=None)  # the end itself is reachable


def test_a_line_leaving_the_workspace_part_way_is_refused_though_the_end_is_reachable():
    # Near full reach, turning the tool over: the wrist centre bulges out of the workspace part-way.
    start = Pose(776.5, 68.4, 508.0, -109.4, 167.5, 21.5)
    end = Pose(754.8, 80.5, 681.7, -165.9, 31.6, -153.0)
    ctl = at(Controller(), start)
    with pytest.raises(RobotError) as err:
        ctl.plan_line(end)
    assert err.value.code == ErrorCode.OUT_OF_REACH and err.value.message.startswith("line 27/175 mm")
    kin.inverse(end, ctl.trajectory.end_deg)  # the end itself is reachable


def test_a_refused_line_consumes_the_one_shot_speed():
    ctl = at(Controller(), A)
    ctl.pending_speed_pct = 10.0
    with pytest.raises(RobotError):
        list(ctl.move_line(Pose(2000.0, 0.0, 400.0, 0.0, 180.0, 0.0)))
    assert ctl.pending_speed_pct is None


def test_a_stop_during_a_line_decelerates_along_it():
    ctl = at(Controller(), A)
    seg = run_line(ctl, B, 20.0)
    t_stop = seg.t0_s + seg.duration_s / 2
    t_rest = ctl.trajectory.stop(t_stop)
    assert 0.0 < t_rest - t_stop <= 0.2, "about one ramp"
    for t in np.linspace(t_stop, t_rest + 0.1, 200):
        assert off_line(kin.forward(ctl.trajectory.position(float(t))))[0] < 0.01
    rest = kin.forward(ctl.trajectory.position(t_rest + 1.0))
    dist, f = off_line(rest)
    assert 0.5 < f < 0.7, "it goes on a little past where the stop came, then rests"
    assert not ctl.trajectory.in_motion(t_rest + 0.001)


def test_line_skills_ack_like_the_motion_skills_and_refuse_bad_numbers():
    ctl = at(Controller(), A)
    ctl.connect("c")
    t = ctl.now_s
    out = ctl.handle(b"00000001:move_to_s:400,150,400,0,180,30", "c", t)
    assert out[0].ack.status is Status.DONE and out[0].ack.t_done_s == t, "acks as the line starts"
    assert ctl.handle(b"00000002:break", "c", t) == []
    (brk,) = ctl.step(ctl.next_wake_s())
    assert poses_close(brk.ack.pose, B, tol_mm=1e-6, tol_deg=1e-6)
    cases = [(b"00000003:depart:100000", ErrorCode.ILLEGAL_VALUE),
             (b"00000004:appro:1,2,3,4,5,6", ErrorCode.WRONG_ARGUMENT_COUNT),
             (b"00000005:appros:400,0,400,0,400,0,10", ErrorCode.ILLEGAL_VALUE)]
    for line, code in cases:
        (o,) = ctl.handle(line, "c", ctl.now_s)
        assert (o.ack.status, o.ack.error_code) == (Status.ERROR, code), o


def test_appro_and_depart_use_the_tool_z_axis_with_v_plus_signs():
    ctl = at(Controller(), A)
    ctl.connect("c")
    for line, z in [(b"00000001:appro:400,0,400,0,180,0,50", 450.0), (b"00000003:departs:25", 475.0),
                    (b"00000005:appros:400,0,400,0,180,0,-10", 390.0), (b"00000007:depart:-10", 380.0)]:
        (o,) = ctl.handle(line, "c", ctl.now_s)
        assert o.ack.ok, o
        ctl.handle(b"0000000f:break", "c", ctl.now_s)
        (brk,) = ctl.step(ctl.next_wake_s())
        assert poses_close(brk.ack.pose, Pose(400.0, 0.0, z, 0.0, 180.0, 0.0), tol_mm=1e-6, tol_deg=1e-6), line


def test_forward_processing_of_lines_is_one_motion_deep():
    # MOVES a; MOVES b; BREAK: a acks at once, b when a begins to decelerate, the break when b is done.
    ctl = at(Controller(), A)
    ctl.connect("c")
    t = ctl.now_s
    (first,) = ctl.handle(b"00000001:move_to_s:400,150,400,0,180,30", "c", t)
    assert first.ack.t_done_s == t
    assert ctl.handle(b"00000002:move_to_s:400,150,500,0,180,30", "c", t) == []
    line_a = ctl.trajectory._segments[-1]
    (second,) = ctl.step(ctl.next_wake_s())
    assert second.ack.t_done_s == pytest.approx(line_a.t_end_s - line_a.ramp_s)
    ctl.handle(b"00000003:break", "c", ctl.now_s)
    (brk,) = ctl.step(ctl.next_wake_s())
    assert brk.ack.t_done_s == pytest.approx(ctl.trajectory.t_rest_s)
    assert poses_close(brk.ack.pose, Pose(400.0, 150.0, 500.0, 0.0, 180.0, 30.0), tol_mm=1e-6, tol_deg=1e-6)


@pytest.mark.parametrize("tool", [Pose(), Pose(0.0, 30.0, 120.0, 0.0, 20.0, 0.0)])
def test_every_accepted_line_stays_on_the_line_and_its_joints_never_jump(tool):
    # Random pairs of poses in front of the arm (seeded): each line is refused before moving or, once accepted,
    # keeps the tool point within micrometres of the line with continuous joints.
    rng = np.random.default_rng(19)
    accepted = 0
    for _ in range(40):
        def pose() -> Pose:
            r, a = rng.uniform(350, 750), rng.uniform(-60, 60)
            return Pose(r * math.cos(math.radians(a)), r * math.sin(math.radians(a)), rng.uniform(150, 750),
                        rng.uniform(-180, 180), rng.uniform(90, 180), rng.uniform(-180, 180))
        a, b = pose(), pose()
        ctl = Controller(tool=tool)
        try:
            at(ctl, a)
            seg = run_line(ctl, b)
        except RobotError:
            continue
        accepted += 1
        start = kin.forward(seg.start_deg, tool)
        prev = None
        for t in np.linspace(seg.t0_s, seg.t_end_s, 200):
            q = np.array(ctl.trajectory.position(float(t)))
            p = kin.forward(q, tool)
            dist, _ = off_line(p, start, b)
            assert dist < 0.01, (a, b, t, dist)
            if prev is not None:
                assert np.max(np.abs(q - prev)) < 15.0, "no joint jumps between two of 200 samples"
            prev = q
        assert poses_close(kin.forward(seg.end_deg, tool), b, tol_mm=1e-6, tol_deg=1e-6)
    assert accepted >= 10, "the test must see lines that run"


def test_the_cartesian_speed_option_reaches_the_one_robot_model():
    from aioadept.cli.sim import build_parser, options_from_args

    args = build_parser().parse_args(["--cartesian-speed", "500,90"])
    ctl = options_from_args(args).make_controller()  # both backends build their controller here
    assert ctl.trajectory.cartesian == CartesianLimits(500.0, 90.0)
    assert build_parser().parse_args([]).cartesian_speed == CartesianLimits()
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--cartesian-speed", "-1"])
