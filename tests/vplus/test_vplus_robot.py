"""RobotDevice, the V+ emulator's robot, driven with a fake time loop (no sockets, no sleeping)."""

from __future__ import annotations

import math

import pytest

from aioadept.robots import viper_s850 as kin
from aioadept.sim.controller import Controller
from aioadept.vplus.locations import PrecisionPoint, decompose, ppoint, trans
from aioadept.vplus.robot import INRANGE_BITS, VPLUS_ERRORS, RobotDevice, VPlusRobotError, inrange_reasons

T = 1  # the task that attaches the robot
A = trans(400, 100, 500, 0, 180, 0)
B = trans(400, -100, 450, 0, 180, 0)
FAR = trans(2000, 0, 500, 0, 180, 0)


def run(robot: RobotDevice, gen) -> list[float]:
    """Drive one instruction to completion the way the interpreter does; return the times it asked for."""
    wakes = []
    for wake in gen:
        assert wake >= robot.now_s - 1e-12, "an instruction asked to be resumed in the past"
        wakes.append(wake)
        robot.now_s = wake
    return wakes


@pytest.fixture
def robot() -> RobotDevice:
    r = RobotDevice(Controller())
    r.now_s = 0.0
    r.attach(T)
    return r


def test_motion_needs_the_robot_attached_by_that_task():
    r = RobotDevice(Controller())
    with pytest.raises(VPlusRobotError) as err:
        run(r, r.move(T, A))
    assert err.value.code == VPLUS_ERRORS["not_attached"].code
    r.attach(T)
    with pytest.raises(VPlusRobotError) as err:
        r.attach(2)
    assert err.value.code == VPLUS_ERRORS["attached"].code
    with pytest.raises(VPlusRobotError):
        run(r, r.move(2, A))
    r.detach(2)  # not the owner: no effect
    assert r.owner == T
    r.detach(T)
    r.attach(2)
    assert r.owner == 2
    assert r.controller.trajectory.t_rest_s == -math.inf, "no motion was planned by refused instructions"


def test_forward_processing_is_one_motion_deep(robot):
    assert run(robot, robot.move(T, A)) == [], "the first MOVE returns as soon as its motion has started"
    t_rest_a = robot.controller.trajectory.t_rest_s
    assert t_rest_a > 0.2
    wakes = run(robot, robot.move(T, B))
    assert wakes, "a second MOVE waits for the first motion"
    # it starts where the first begins to decelerate: before the first is done, within one ramp of it
    assert t_rest_a - 0.25 <= robot.now_s < t_rest_a
    run(robot, robot.break_())
    assert robot.now_s == pytest.approx(robot.controller.trajectory.t_rest_s)
    assert not robot.in_motion
    assert robot.here().close(B, tol_mm=1e-6, tol_deg=1e-6)


def test_unreachable_target_is_an_error_before_anything_moves(robot):
    with pytest.raises(VPlusRobotError) as err:
        run(robot, robot.move(T, FAR))
    assert err.value.code == VPLUS_ERRORS["out_of_range"].code
    assert robot.controller.trajectory.t_rest_s == -math.inf
    assert robot.here_ppoint().joints_deg == kin.HOME_JOINTS_DEG


def test_joint_limit_is_an_error_before_anything_moves(robot):
    with pytest.raises(VPlusRobotError) as err:
        run(robot, robot.move(T, ppoint(175, -90, 180, 0, 90, 0)))
    assert err.value.code == VPLUS_ERRORS["joint_limit"].code
    assert robot.controller.trajectory.t_rest_s == -math.inf
    with pytest.raises(VPlusRobotError) as err:
        run(robot, robot.move(T, PrecisionPoint((0.0, 1.0))))
    assert err.value.code == VPLUS_ERRORS["illegal_value"].code


def test_inrange_codes(robot):
    assert robot.inrange(A) == 0
    assert robot.inrange(FAR) == INRANGE_BITS["too_far"]
    # above the base, within the arm's annulus: reachable in space, but only past joint limits
    code = robot.inrange(trans(0, 0, 335, 0, 180, 0))
    assert code & 0x3F and not code & INRANGE_BITS["too_far"]
    assert robot.inrange(ppoint(0, -90, 180, 0, 90, 0)) == 0
    assert robot.inrange(ppoint(175, -90, 180, 0, 90, 0)) == 1  # joint 1: bit 1
    assert robot.inrange(ppoint(0, -90, 260, 0, 125, 0)) == 4 | 16  # joints 3 and 5
    assert inrange_reasons(4 | INRANGE_BITS["too_far"]) == ["joint 3 limit", "too_far"]
    assert inrange_reasons(0) == []


def test_speed_applies_to_the_next_motion_only_unless_always(robot):
    def duration(target) -> float:
        t0 = robot.now_s
        run(robot, robot.move(T, target))
        run(robot, robot.break_())
        return robot.now_s - t0

    # J1 turns 90 deg each way, so the speed, not the fixed acceleration ramps, sets the duration
    there, back = ppoint(90, -90, 180, 0, 90, 0), ppoint(0, -90, 180, 0, 90, 0)
    full = duration(there)
    robot.speed(T, 50)
    half = duration(back)
    assert half > 1.5 * full
    assert duration(there) == pytest.approx(full, rel=1e-6), "SPEED without ALWAYS: the next motion only"
    robot.speed(T, 50, always=True)
    assert duration(back) == pytest.approx(half, rel=1e-6)
    assert duration(there) == pytest.approx(half, rel=1e-6)
    robot.monitor_speed = 50  # effective = program x monitor / 100 = 25 %
    assert duration(back) > 1.5 * half
    with pytest.raises(VPlusRobotError):
        robot.speed(T, 0)
    with pytest.raises(VPlusRobotError):
        robot.monitor_speed = 150
    with pytest.raises(VPlusRobotError):
        robot.speed(2, 50)


def test_brake_stops_short_and_drops_the_waiting_motion(robot):
    run(robot, robot.move(T, A))
    gen = robot.move(T, B)
    wake = next(gen)  # B waits for A to begin decelerating
    robot.now_s = 0.1
    t_rest = robot.brake()  # from another task, e.g. the reader serving a stop
    assert t_rest >= 0.1
    with pytest.raises(StopIteration):
        robot.now_s = max(wake, robot.now_s)
        next(gen)
    run(robot, robot.break_())
    assert robot.now_s == pytest.approx(t_rest)
    here = decompose(robot.here())
    assert not robot.here().close(A, tol_mm=1.0, tol_deg=1.0), "the arm stopped short of A"
    assert not robot.here().close(B, tol_mm=1.0, tol_deg=1.0), "B never started"
    robot.now_s += 10.0
    assert decompose(robot.here()) == pytest.approx(here), "nothing moves after the brake"


def test_dry_run_checks_targets_but_does_not_move(robot):
    robot.dry_run = True
    robot.speed(T, 10)
    assert run(robot, robot.move(T, A)) == []
    assert run(robot, robot.move(T, B)) == []
    assert robot.controller.pending_speed_pct is None, "the one-shot SPEED was consumed"
    assert robot.here_ppoint().joints_deg == kin.HOME_JOINTS_DEG
    with pytest.raises(VPlusRobotError):
        run(robot, robot.move(T, FAR))


def test_appro_and_depart_along_the_tool_z_axis(robot):
    # At home the tool points down (pitch 180): tool -Z is world +Z.
    run(robot, robot.depart(T, 50))
    run(robot, robot.break_())
    x, y, z, *_ = decompose(robot.here())
    assert (x, y, z) == pytest.approx((480, 0, 760), abs=1e-6)
    run(robot, robot.appro(T, A, 30))
    run(robot, robot.break_())
    assert decompose(robot.here())[:3] == pytest.approx((400, 100, 530), abs=1e-6)
    run(robot, robot.moves(T, A))
    run(robot, robot.break_())
    assert robot.here().close(A, tol_mm=1e-6, tol_deg=1e-6)


def test_tool_changes_here(robot):
    before = decompose(robot.here())
    robot.set_tool(T, trans(0, 0, 100))
    assert decompose(robot.tool)[:3] == pytest.approx((0, 0, 100))
    after = decompose(robot.here())
    assert after[2] == pytest.approx(before[2] - 100), "the tool tip is 100 mm below the flange"
    assert robot.here_ppoint().joints_deg == kin.HOME_JOINTS_DEG


def test_delay_waits_for_rest_then_holds(robot):
    robot.controller.trajectory.time_scale = 2.0  # as --time-scale 2
    run(robot, robot.move(T, A))
    t_rest = robot.controller.trajectory.t_rest_s
    run(robot, robot.delay(T, 1.0))
    assert robot.now_s == pytest.approx(t_rest + 0.5)
    with pytest.raises(VPlusRobotError):
        run(robot, robot.delay(T, -1))


def test_robot_errors_are_vplus_program_errors_and_brake_takes_the_time(robot):
    from aioadept.vplus.errors import VPlusError

    with pytest.raises(VPlusError) as err:
        run(robot, robot.move(T, FAR))
    assert err.value.code == VPLUS_ERRORS["out_of_range"].code and "out of range" in err.value.message
    run(robot, robot.move(T, A))
    assert robot.brake(0.05) >= 0.05 and robot.now_s == 0.05


def test_a_brake_from_another_task_ends_a_waiting_break_when_the_arm_stops(robot):
    run(robot, robot.move(T, ppoint(150, -90, 180, 0, 90, 0)))  # about 0.7 s at full speed
    t_planned = robot.controller.trajectory.t_rest_s
    brk = robot.break_()
    robot.now_s = next(brk)
    while robot.now_s < 0.1:  # the break waits; the interpreter resumes it when it asks
        robot.now_s = next(brk)
    t_rest = robot.brake()  # the reader task serves a stop
    assert t_rest < t_planned - 0.2
    for wake in brk:
        robot.now_s = wake
    assert t_rest <= robot.now_s <= t_rest + robot.poll_s + 1e-9, "BREAK returns when the braked arm is at rest"
