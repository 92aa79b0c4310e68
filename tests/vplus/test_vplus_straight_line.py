"""The emulator's MOVES, APPROS, DEPARTS on the controller's one straight-line model: the tool stays on
the line, a line through a singularity is a V+ error before anything moves, BRAKE stops on the line, DRY.RUN
checks the line. Fake time loop, as tests/vplus/test_vplus_robot.py."""

from __future__ import annotations

import numpy as np
import pytest

from aioadept.protocol import ErrorCode
from aioadept.robots import viper_s850 as kin
from aioadept.sim.controller import Controller
from aioadept.vplus.locations import PrecisionPoint, decompose, trans
from aioadept.vplus.robot import RobotDevice, VPlusRobotError

T = 1
A = trans(400, -150, 400, 0, 180, 0)
B = trans(400, 150, 400, 0, 180, 0)


def run(robot: RobotDevice, gen) -> None:
    for wake in gen:
        robot.now_s = wake


@pytest.fixture
def robot() -> RobotDevice:
    r = RobotDevice(Controller())
    r.now_s = 0.0
    r.attach(T)
    run(r, r.move(T, A))
    run(r, r.break_())
    return r


def off_line_mm(robot: RobotDevice, t: float) -> float:
    y = kin.forward(robot.controller.joints_at(t))
    return float(np.hypot(y.x - 400.0, y.z - 400.0))


def test_moves_keeps_the_tool_on_the_line_and_move_does_not(robot):
    t0 = robot.now_s
    run(robot, robot.moves(T, B))
    t1 = robot.controller.trajectory.t_rest_s
    assert max(off_line_mm(robot, t) for t in np.linspace(t0, t1, 300)) < 0.01
    run(robot, robot.break_())
    assert robot.here().close(B, tol_mm=1e-6, tol_deg=1e-6)
    t0 = robot.now_s
    run(robot, robot.move(T, A))
    t1 = robot.controller.trajectory.t_rest_s
    assert max(off_line_mm(robot, t) for t in np.linspace(t0, t1, 300)) > 2.0


def test_a_line_through_the_wrist_singularity_is_a_v_plus_error_before_anything_moves(robot):
    a, b = trans(560, -50, 785, 0, 90, 0), trans(560, 50, 785, 0, 90, 0)
    run(robot, robot.move(T, a))
    run(robot, robot.break_())
    before = robot.here_ppoint().joints_deg
    with pytest.raises(VPlusRobotError) as err:
        run(robot, robot.moves(T, b))
    assert err.value.code == ErrorCode.JOINT_JUMP and "singularity" in str(err.value)
    assert robot.here_ppoint().joints_deg == before and not robot.in_motion


def test_brake_during_moves_stops_the_tool_on_the_line(robot):
    robot.speed(T, 20)
    run(robot, robot.moves(T, B))
    robot.now_s = robot.now_s + 0.4
    t_rest = robot.brake()
    for t in np.linspace(robot.now_s, t_rest + 0.1, 100):
        assert off_line_mm(robot, float(t)) < 0.01
    y = decompose(robot.here())[1]
    assert -150 < y < 150


def test_appros_departs_and_moves_to_a_precision_point(robot):
    run(robot, robot.appro(T, trans(400, 0, 400, 0, 180, 0), 40, straight=True))
    run(robot, robot.break_())
    assert decompose(robot.here())[:3] == pytest.approx((400, 0, 440), abs=1e-6)
    run(robot, robot.depart(T, 20, straight=True))
    run(robot, robot.break_())
    assert decompose(robot.here())[:3] == pytest.approx((400, 0, 460), abs=1e-6)
    run(robot, robot.moves(T, PrecisionPoint(kin.HOME_JOINTS_DEG)))
    run(robot, robot.break_())
    assert robot.here_ppoint().joints_deg == pytest.approx(kin.HOME_JOINTS_DEG, abs=1e-6)


def test_dry_run_checks_the_whole_line_without_moving(robot):
    # Both ends reachable (J1 at +-160 deg); the line between them passes behind the base, past J1's limit.
    r, ang = 500.0, np.radians(160.0)
    start = trans(r * np.cos(ang), r * np.sin(ang), 400, 0, 180, 0)
    end = trans(r * np.cos(ang), -r * np.sin(ang), 400, 0, 180, 0)
    run(robot, robot.move(T, start))
    run(robot, robot.break_())
    robot.dry_run = True
    run(robot, robot.move(T, end))  # the joint move is fine (J1 turns the other way round)
    with pytest.raises(VPlusRobotError) as err:
        run(robot, robot.moves(T, end))
    assert err.value.code == ErrorCode.JOINT_LIMIT
    assert robot.here().close(start, tol_mm=1e-6, tol_deg=1e-6), "nothing moved"
