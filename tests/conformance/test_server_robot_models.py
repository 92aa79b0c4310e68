"""The Python sim serves every robot model (``aioadept sim --robot-model NAME``) over real TCP: the paper's skills
with the model's kinematics, limits and home, and on a Cobra the SCARA's semantics (four joints, the tool pointing
down, another pitch refused before anything moves). The V+ emulator runs the Viper s850 only so far, and says so."""

from __future__ import annotations

import asyncio
import math

import pytest

from aioadept.cli.sim import main
from aioadept.geometry import Pose, poses_close
from aioadept.protocol import ErrorCode, Status
from aioadept.robots import MODELS, model

NAMES = sorted(MODELS)


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
@pytest.mark.parametrize("name", NAMES)
async def test_the_sim_serves_the_paper_skills_on_each_model(start_server, name):
    m = model(name)
    async with start_server("python", "--robot-model", name, "--time-scale", "5") as srv:
        c = await srv.connect()
        await c.send("aaaa0001:here")
        here = await c.ack()
        assert poses_close(here.pose, m.forward(m.home_deg), tol_mm=0.01, tol_deg=0.01), "starts at its home"
        assert [float(v) for v in here.extra[0].split(",")] == pytest.approx(m.home_deg, abs=1e-3)

        goal = _target(m)
        pose = m.forward(goal)
        await c.send(f"aaaa0002:move_to:{_fmt(pose)}", "aaaa0003:break", "aaaa0004:here")
        mv, brk, here = await c.acks(3, 60)
        assert (mv.status, brk.status) == (Status.DONE, Status.DONE), (mv, brk)
        assert poses_close(here.pose, pose, tol_mm=0.01, tol_deg=0.01)
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


@pytest.mark.timeout(120)
@pytest.mark.parametrize("name", [n for n in NAMES if n.startswith("cobra")])
async def test_a_cobra_refuses_what_a_scara_cannot_do_and_nothing_moves(start_server, name):
    m = model(name)
    async with start_server("python", "--robot-model", name, "--time-scale", "5") as srv:
        c = await srv.connect()
        await c.send("bbbb0001:here")
        home = (await c.ack()).pose
        tilted = Pose(home.x, home.y, home.z, 0.0, 170.0, home.roll)
        cases = [
            (f"bbbb0002:move_to:{_fmt(tilted)}", ErrorCode.OUT_OF_REACH, "orientation not possible"),
            (f"bbbb0003:move_to_s:{_fmt(tilted)}", ErrorCode.OUT_OF_REACH, "orientation not possible"),
            ("bbbb0004:move_rel_tool:0,0,0,0,10,0", ErrorCode.OUT_OF_REACH, "orientation not possible"),
            (f"bbbb0005:move_joints:{_fmt(list(m.home_deg) + [5.0, 0.0])}", ErrorCode.ILLEGAL_VALUE, "4 joints"),
            ("bbbb0006:move_rel_joints:0,0,0,0,0,3", ErrorCode.ILLEGAL_VALUE, "4 joints"),
            (f"bbbb0007:move_to:{_fmt(Pose(home.x, home.y, home.z - m.limits.max_deg[2], 0, 180, 0))}",
             ErrorCode.JOINT_LIMIT, "J3"),
        ]
        for line, code, text in cases:
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
@pytest.mark.parametrize("name", NAMES)
async def test_a_stop_from_another_connection_halts_each_model_and_nothing_moves_after(start_server, name):
    """The stop path on every model: J1 across most of its range at 10 % is a motion of seconds; a stop from a
    second connection aborts the waiting break, is done once the arm rests short of the target, and the arm
    stays there."""
    m = model(name)
    target = list(m.home_deg)
    target[0] = m.limits.max_deg[0] - 5.0
    async with start_server("python", "--robot-model", name) as srv:
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


def test_the_vplus_emulator_refuses_another_model_in_one_line(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--vplus", "vplus/rserver.V2", "--run", "rs.main", "--robot-model", "cobra-s600"])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--robot-model cobra-s600: sim --vplus serves the viper-s850 only so far" in err
