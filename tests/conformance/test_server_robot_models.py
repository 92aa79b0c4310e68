"""Both backends serve every robot model (``aioadept sim --robot-model NAME``, and with ``--vplus`` the shipped V+
server on the emulator) over real TCP: the paper's skills with the model's kinematics, limits and home, and on a
Cobra the SCARA's semantics (four joints, the tool pointing down, another pitch refused before anything moves).
The Python sim runs each test on every model; the V+ server, slower to start, on one Cobra and the Viper s650
(the s850 is the rest of the conformance suite's arm)."""

from __future__ import annotations

import asyncio
import math

import pytest

from aioadept.cli.sim import main
from aioadept.geometry import Pose, poses_close
from aioadept.protocol import ErrorCode, Status
from aioadept.robots import MODELS, model

NAMES = sorted(MODELS)
ON_VPLUS = ["cobra-s600", "viper-s650"]
"""The models the V+ server is run on here: one of each family besides the suite's s850."""


def _cases(names):
    return [("python", n) for n in names] + [("vplus", n) for n in names if n in ON_VPLUS]


def _fmt(values) -> str:
    return ",".join(f"{v:.3f}" for v in values)


def _wire_joints(m, q) -> str:
    return _fmt(list(q) + [0.0] * (6 - m.dof))


def _target(m) -> tuple[float, ...]:
    """Joints a little way from home, in the same configuration, well inside the limits."""
    q = list(m.home_deg)
    q[0] += 20.0
    q[1] += -10.0 if m.family == "viper" else 15.0
    q[2] += 10.0
    q[3] += 30.0
    return tuple(q)


@pytest.mark.timeout(120)
@pytest.mark.parametrize("backend,robot_model", _cases(NAMES))
async def test_the_sim_serves_the_paper_skills_on_each_model(start_server, backend, robot_model):
    m = model(robot_model)
    async with start_server(backend, "--time-scale", "5") as srv:
        c = await srv.connect()
        await c.send("aaaa0001:here")
        here = await c.ack()
        assert poses_close(here.pose, m.forward(m.home_deg), tol_mm=0.01, tol_deg=0.01), "starts at its home"
        if backend == "python":  # the V+ server's here carries the pose only
            assert [float(v) for v in here.extra[0].split(",")] == pytest.approx(m.home_deg, abs=1e-3)

        goal = _target(m)
        pose = m.forward(goal)
        await c.send(f"aaaa0002:move_to:{_fmt(pose)}", "aaaa0003:break", "aaaa0004:here")
        mv, brk, here = await c.acks(3, 60)
        assert (mv.status, brk.status) == (Status.DONE, Status.DONE), (mv, brk)
        assert poses_close(here.pose, pose, tol_mm=0.01, tol_deg=0.01)
        if backend == "python":
            assert [float(v) for v in here.extra[0].split(",")] == pytest.approx(goal, abs=1e-3)

        # 20 mm along the tool's z: straight down on a Cobra (its tool points down), and a straight line back up
        await c.send("aaaa0005:move_rel_tool:0,0,20,0,0,0", "aaaa0006:break",
                     f"aaaa0007:move_to_s:{_fmt(pose)}", "aaaa0008:break")
        rel, relb, line, back = await c.acks(4, 60)
        assert rel.status == relb.status == line.status == back.status == Status.DONE, (rel, line, back)
        moved = relb.pose.to_matrix()[:3, 3] - pose.to_matrix()[:3, 3]
        tool_z = pose.to_matrix()[:3, 2]
        assert moved == pytest.approx(20.0 * tool_z, abs=0.01)
        assert poses_close(back.pose, pose, tol_mm=0.01, tol_deg=0.01)

        # appro / departs: 50 mm back along the tool's z
        await c.send(f"aaaa0009:appro:{_fmt(pose)},50", "aaaa0010:break", "aaaa0011:departs:30",
                     "aaaa0012:break")
        ap, apb, dep, depb = await c.acks(4, 60)
        assert Status.ERROR not in (ap.status, apb.status, dep.status, depb.status), (ap, dep)
        assert apb.pose.translation_distance_mm(pose) == pytest.approx(50.0, abs=0.01)
        assert depb.pose.translation_distance_mm(pose) == pytest.approx(80.0, abs=0.01)

        # a joint past its limit: refused, nothing moves
        q = list(depb.pose)
        past = list(m.home_deg)
        past[0] = m.limits.max_deg[0] + 1.0
        await c.send(f"aaaa0013:move_joints:{_wire_joints(m, past)}", "aaaa0014:here")
        err, still = await c.acks(2)
        assert (err.status, err.error_code) == (Status.ERROR, ErrorCode.JOINT_LIMIT), err
        assert list(still.pose) == pytest.approx(q, abs=1e-6)
        await c.close()


OUT, ILLEGAL, FAILED = ErrorCode.OUT_OF_REACH, ErrorCode.ILLEGAL_VALUE, ErrorCode.SKILL_FAILED
REFUSED = {
    # What each backend answers (code, words of the message). The V+ server refuses a Cartesian target that INRANGE
    # says cannot be reached with -610 whatever the reason (docs/vplus.md), and a straight line is refused by MOVES
    # itself: V+'s error through REACTE, -300 carrying it.
    "python": [(OUT, "orientation not possible"), (OUT, "orientation not possible"),
               (OUT, "orientation not possible"), (ILLEGAL, "4 joints"), (ILLEGAL, "4 joints"),
               (ErrorCode.JOINT_LIMIT, "J3")],
    "vplus": [(OUT, "out of range"), (FAILED, "V+ -610 *Location out of range*"), (OUT, "out of range"),
              (ILLEGAL, "4 joints"), (ILLEGAL, "4 joints"), (OUT, "out of range")],
}


@pytest.mark.timeout(120)
@pytest.mark.parametrize("backend,robot_model", _cases([n for n in NAMES if n.startswith("cobra")]))
async def test_a_cobra_refuses_what_a_scara_cannot_do_and_nothing_moves(start_server, backend, robot_model):
    m = model(robot_model)
    async with start_server(backend, "--time-scale", "5") as srv:
        c = await srv.connect()
        await c.send("bbbb0001:here")
        home = (await c.ack()).pose
        tilted = Pose(home.x, home.y, home.z, 0.0, 170.0, home.roll)
        lines = [f"bbbb0002:move_to:{_fmt(tilted)}", f"bbbb0003:move_to_s:{_fmt(tilted)}",
                 "bbbb0004:move_rel_tool:0,0,0,0,10,0", f"bbbb0005:move_joints:{_fmt(list(m.home_deg) + [5.0, 0.0])}",
                 "bbbb0006:move_rel_joints:0,0,0,0,0,3",
                 f"bbbb0007:move_to:{_fmt(Pose(home.x, home.y, home.z - m.limits.max_deg[2], 0, 180, 0))}"]
        for line, (code, text) in zip(lines, REFUSED[backend], strict=True):
            await c.send(line, "bbbb0099:break")
            ack, brk = await c.acks(2, 30)
            assert (ack.id, ack.status, ack.error_code) == (line[:8], Status.ERROR, code), ack
            assert text in ":".join(ack.extra[1:]), ack
            assert poses_close(brk.pose, home, tol_mm=1e-6, tol_deg=1e-6), "nothing moved"

        # J3 is mm: a joint move of the quill by 30 lowers the tool by 30 mm, J4 turns it about the vertical
        q = list(m.home_deg)
        q[2] += 30.0
        q[3] += 45.0
        await c.send(f"bbbb0010:move_joints:{_wire_joints(m, q)}", "bbbb0011:break")
        mv, brk = await c.acks(2, 30)
        assert mv.status == brk.status == Status.DONE
        assert (brk.pose.x, brk.pose.y, brk.pose.z) == pytest.approx((home.x, home.y, home.z - 30.0), abs=1e-3)
        assert (brk.pose.yaw, brk.pose.pitch) == (0.0, 180.0)
        assert math.remainder(brk.pose.roll - home.roll - 45.0, 360.0) == pytest.approx(0.0, abs=1e-3)
        await c.close()


@pytest.mark.timeout(120)
@pytest.mark.parametrize("backend,robot_model", [("python", n) for n in NAMES] + [("vplus", "cobra-s600")])
async def test_a_stop_from_another_connection_halts_each_model_and_nothing_moves_after(start_server, backend,
                                                                                         robot_model):
    """The stop path on every model (on the V+ server: the Cobra; its six-joint path is the suite's s850's): J1
    across most of its range at 10 % is a motion of seconds; a stop from a second connection aborts the waiting
    break, is done once the arm rests short of the target, and the arm stays there."""
    m = model(robot_model)
    target = list(m.home_deg)
    target[0] = m.limits.max_deg[0] - 5.0
    async with start_server(backend) as srv:
        a, b = await srv.connect(), await srv.connect()
        await a.send("dddd0001:set_speed:10", f"dddd0002:move_joints:{_wire_joints(m, target)}", "dddd0003:break")
        speed, move = await a.acks(2)
        assert speed.ok and move.ok, (speed, move)
        await asyncio.sleep(0.3)
        await b.send("eeee0001:stop")
        brk, stop = await a.ack(20), await b.ack(20)
        assert (brk.id, brk.status) == ("dddd0003", Status.ABORTED)
        assert (stop.id, stop.status) == ("eeee0001", Status.DONE)
        await b.send("eeee0002:here")
        rest = await b.ack()
        assert not poses_close(rest.pose, m.forward(target), tol_mm=1.0, tol_deg=1.0), "stopped short"
        await asyncio.sleep(0.5)
        await b.send("eeee0003:here")
        again = await b.ack()
        assert again.extra == rest.extra and poses_close(again.pose, rest.pose, tol_mm=1e-6, tol_deg=1e-6)
        await a.close()
        await b.close()


def test_an_unknown_model_is_one_line_naming_the_known_ones(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--robot-model", "cobra-s1000"])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "unknown robot model 'cobra-s1000'" in err and "cobra-s600" in err


