"""Straight-line and approach skills on every backend: ``move_to_s``, ``move_rel_tool_s``, ``appro``,
``appros``, ``depart``, ``departs``, over real TCP, with the same assertions for the Python sim and the V+ server on
the emulator (conftest.py).

Poses are about the robot model's work point (fixture ``arm``), tool pointing down, so each test means the same on
a Viper and a Cobra. The line is checked by sampling the arm while it moves: a second connection with nothing pending asks ``here``,
which both servers answer at once from the current state (docs/protocol.md 4.5), as fast as the answers come.
The same sampling of a joint-interpolated ``move_to`` between the same ends must see the tool leave the line, so
the check can fail. Timing bounds are generous (the machine is shared).
"""

from __future__ import annotations

import asyncio
import math
import re
import sys

import numpy as np
import pytest

from aioadept.geometry import Pose, poses_close, zyz_to_rotation
from aioadept.protocol import Ack, ErrorCode, Status
from aioadept.sim.line import line_pose_matrix
from modelarm import Arm

LINE_TOL_MM = 0.5
wire = Arm.pose_wire


def ends(arm: Arm) -> tuple[Pose, Pose]:
    """A 300 mm line in front of the arm, tool pointing down, turning 30 deg about its axis on the way."""
    return arm.at(0, -150, 0), arm.at(0, 150, 0, roll=30)


def v_code(ack: Ack) -> int | None:
    """The V+-level error code of an error ack. The V+ server reports an error V+ itself raised inside a skill
    (MOVES refusing a line) as -300 with ``V+ <code> <text>`` in the message (docs/vplus.md, rs.onerr); the Python
    sim answers the code itself. Both mean the same refusal."""
    if ack.error_code == ErrorCode.SKILL_FAILED:
        m = re.search(r"V\+ (-\d+)", ack.error_message or "")
        if m:
            return int(m.group(1))
    return ack.error_code


def off_line_mm(p: Pose, a: Pose, b: Pose) -> tuple[float, float]:
    """(distance of p's position from the segment a-b in mm, the fraction along it of its projection)."""
    pa, pb, pp = a.position_mm, b.position_mm, p.position_mm
    d = pb - pa
    f = float(np.clip((pp - pa) @ d / (d @ d), 0.0, 1.0))
    return float(np.linalg.norm(pp - (pa + f * d))), f


def orientation_error_deg(p: Pose, f: float, a: Pose, b: Pose) -> float:
    """Angle between p's orientation and the slerp of a's and b's at fraction f."""
    want = line_pose_matrix(a.to_matrix(), b.to_matrix(), f)[:3, :3]
    r = want.T @ zyz_to_rotation(p.yaw, p.pitch, p.roll)
    return math.degrees(math.acos(max(-1.0, min(1.0, (float(np.trace(r)) - 1.0) / 2.0))))


async def go(c, pose: Pose, tag: str) -> None:
    await c.send(f"{tag}0001:move_to:{wire(pose)}", f"{tag}0002:break")
    move, brk = await c.acks(2, timeout=30)
    assert move.ok and brk.ok, (move, brk)
    assert poses_close(brk.pose, pose, tol_mm=0.01, tol_deg=0.01)


async def sample_while_moving(server, c, lines: list[str], tag: str) -> tuple[list[Ack], list[Pose]]:
    """Send ``lines`` (ending with a break) on ``c`` and sample ``here`` on a second connection until the break's
    ack arrives; returns (the acks of ``lines``, the poses sampled)."""
    probe = await server.connect()
    await c.send(*lines)
    done = asyncio.ensure_future(c.acks(len(lines), timeout=30))
    poses: list[Pose] = []
    n = 0
    while not done.done():
        n += 1
        await probe.send(f"{tag}{n:04x}:here")
        ack = await probe.ack()
        assert ack.ok, ack
        poses.append(ack.pose)
    acks = await done
    await probe.close()
    return acks, poses


@pytest.mark.timeout(120)
@pytest.mark.every_model
async def test_move_to_s_keeps_the_tool_on_the_line_at_the_straight_line_speed(server, arm):
    A, B = ends(arm)
    c = await server.connect()
    await go(c, A, "aa00")
    # 10 % of the 2000 mm/s straight-line speed: 300 mm take about 1.5 s plus the ramps.
    (speed, move, brk), poses = await sample_while_moving(
        server, c, ["ab000001:set_speed:10", f"ab000002:move_to_s:{wire(B)}", "ab000003:break"], "ac00")
    assert speed.ok and move.ok and brk.ok, (speed, move, brk)
    assert poses_close(brk.pose, B, tol_mm=0.01, tol_deg=0.01), "the line ends at the target"
    inside = []
    for p in poses:
        dist, f = off_line_mm(p, A, B)
        assert dist <= LINE_TOL_MM, f"{p} is {dist:.3f} mm off the line"
        assert orientation_error_deg(p, f, A, B) <= 0.5, f"{p}: orientation off the slerp"
        if 0.05 < f < 0.95:
            inside.append(p)
    assert len(inside) >= 10, f"only {len(inside)} samples in the middle of the line: the check saw no motion"
    assert 1.2 <= brk.t_done_s - move.t_done_s <= 4.0, "straight-line speed: 300 mm at 10 % of 2000 mm/s"

    # The same sampling sees a joint-interpolated move between the same ends leave the line.
    await go(c, A, "ad00")
    (speed, move, brk), poses = await sample_while_moving(
        server, c, ["ae000001:set_speed:10", f"ae000002:move_to:{wire(B)}", "ae000003:break"], "af00")
    assert brk.ok
    assert max(off_line_mm(p, A, B)[0] for p in poses) > 2.0, "a joint move bows away from the line"
    await c.close()


@pytest.mark.timeout(120)
async def test_stop_during_a_straight_line_brings_the_tool_to_rest_on_the_line(server, arm):
    A, B = ends(arm)
    c = await server.connect()
    await go(c, A, "ba00")
    await c.send("bb000001:set_speed:10", f"bb000002:move_to_s:{wire(B)}", "bb000003:break")
    speed, move = await c.acks(2)
    assert speed.ok and move.ok
    await asyncio.sleep(0.6)  # mid-line (the line takes about 1.6 s): a stop while moving, not a readiness wait
    other = await server.connect()
    await other.send("bc000001:stop")
    brk = await c.ack(20)
    stop = await other.ack(20)
    assert (brk.status, stop.status) == (Status.ABORTED, Status.DONE)
    await other.send("bc000002:here")
    rest = (await other.ack()).pose
    dist, f = off_line_mm(rest, A, B)
    assert dist <= LINE_TOL_MM, f"stopped {dist:.3f} mm off the line"
    assert 0.05 < f < 0.95, f"stopped part-way ({f:.2f} of the line)"
    await asyncio.sleep(0.3)
    await other.send("bc000003:here")
    assert poses_close((await other.ack()).pose, rest, tol_mm=0.01, tol_deg=0.01), "and it stays there"
    await other.close()
    await c.close()


@pytest.mark.timeout(120)
@pytest.mark.every_model
async def test_move_rel_tool_s_appro_appros_depart_departs(server, arm):
    c = await server.connect()
    p = arm.at()
    await go(c, p, "ca00")
    # Tool Z points down (on a Viper here, on a Cobra always): -40 along it is 40 mm up in the world.
    await c.send("cb000001:move_rel_tool_s:0.000,0.000,-40.000,0.000,0.000,0.000", "cb000002:break")
    move, brk = await c.acks(2)
    assert move.ok and brk.ok and poses_close(brk.pose, arm.at(dz=40), tol_mm=0.01, tol_deg=0.01)
    steps = [(f"cc000001:appro:{wire(p, 50)}", 50.0),        # 50 mm from p back along its tool Z: above it
             (f"cc000003:appros:{wire(p, 20)}", 20.0),
             ("cc000005:depart:30.000", 50.0),               # the tool backs off along its own Z: up
             ("cc000007:departs:-10.000", 40.0)]             # a negative distance goes the other way
    for i, (line, dz) in enumerate(steps):
        await c.send(line, f"cd00000{i}:break")
        move, brk = await c.acks(2)
        assert move.ok and brk.ok, (line, move, brk)
        assert poses_close(brk.pose, arm.at(dz=dz), tol_mm=0.01, tol_deg=0.01), (line, brk.pose)
    await c.close()


BULGE = {
    "viper-s850": (Pose(776.5, 68.4, 508.0, -109.4, 167.5, 21.5), Pose(754.8, 80.5, 681.7, -165.9, 31.6, -153.0)),
    "viper-s650": (Pose(589.9, 63.1, 400.1, -125.0, 149.3, 5.5), Pose(593.7, 14.5, 577.8, -163.3, 24.8, -156.5)),
}
"""Per Viper, two reachable poses near full reach, the tool turned over between them, whose straight line takes the
wrist centre out of the workspace part-way (the s650's found by a search about the s850's joints)."""


@pytest.mark.viper_only
@pytest.mark.timeout(120)
async def test_lines_through_a_singularity_past_a_joint_limit_or_out_of_reach_are_refused_before_moving(server, arm):
    """Viper-only by nature: the line passes a wrist singularity (J5 = 0), which a SCARA has not, and its poses
    (the tool horizontal, the tool turned over) are orientations a SCARA refuses anyway (test_server_robot_models
    checks those refusals)."""
    m = arm.m
    c = await server.connect()
    # Tool horizontal along +x, wrist centre 5 mm below the forearm's axis (J2 -90, J3 180): crossing y = 0 the
    # wrist passes next to its singularity (J5 = 0) and J4 would have to spin half a turn.
    x, z = m.a1 + m.d4 + m.d6, m.d1 + m.a2 + m.a3 - 5.0
    a = Pose(x, -50.0, z, 0.0, 90.0, 0.0)
    await go(c, a, "da00")
    await c.send(f"db000001:move_to_s:{wire(Pose(x, 50.0, z, 0.0, 90.0, 0.0))}", "db000002:here")
    ack, here = await c.acks(2)
    assert (ack.id, ack.status, v_code(ack)) == ("db000001", Status.ERROR, ErrorCode.JOINT_JUMP), ack
    assert ack.pose == here.pose and poses_close(here.pose, a, tol_mm=0.01, tol_deg=0.01), "nothing moved"

    # Both ends reachable, 20 deg either side of the arm's back; the line between them passes behind the base,
    # where J1 would have to go past +-170.
    r, ang = 500.0, math.radians(160.0)
    start = Pose(r * math.cos(ang), r * math.sin(ang), 400.0, 0.0, 180.0, 0.0)
    end = Pose(r * math.cos(ang), -r * math.sin(ang), 400.0, 0.0, 180.0, 0.0)
    await go(c, start, "dc00")
    await c.send(f"dd000001:move_to_s:{wire(end)}", "dd000002:break", "dd000003:here")
    ack, brk, here = await c.acks(3)
    assert (ack.status, v_code(ack)) == (Status.ERROR, ErrorCode.JOINT_LIMIT), ack
    assert brk.ok and poses_close(here.pose, start, tol_mm=0.01, tol_deg=0.01), "nothing moved"

    # The joint-interpolated move to the same end is fine (J1 turns the other way round): only the line is refused.
    await c.send(f"de000001:move_to:{wire(end)}", "de000002:break")
    move, brk = await c.acks(2, timeout=30)
    assert move.ok and brk.ok and poses_close(brk.pose, end, tol_mm=0.01, tol_deg=0.01)

    # Near full reach, turning the tool over: the wrist centre bulges out of the workspace part-way.
    start, end = BULGE[arm.name]
    await go(c, start, "df00")
    await c.send(f"dg000001:move_to_s:{wire(end)}", "dg000002:here", f"dg000003:move_to:{wire(end)}", "dg000004:break")
    ack, here, move, brk = await c.acks(4, timeout=30)
    assert (ack.status, v_code(ack)) == (Status.ERROR, ErrorCode.OUT_OF_REACH), ack
    assert poses_close(here.pose, start, tol_mm=0.01, tol_deg=0.01), "nothing moved"
    assert move.ok and brk.ok and poses_close(brk.pose, end, tol_mm=0.01, tol_deg=0.01), "the end is reachable"
    await c.close()


@pytest.mark.timeout(90)
async def test_bad_arguments_get_one_error_ack_and_the_connection_stays_usable(server):
    c = await server.connect()
    await c.send("ea000001:here")
    before = (await c.ack()).pose
    cases = [("ea000002:move_to_s:2000.000,0.000,500.000,0.000,180.000,0.000", ErrorCode.OUT_OF_REACH),
             ("ea000003:appro:400.000,0.000,400.000,0.000,180.000,0.000", ErrorCode.WRONG_ARGUMENT_COUNT),
             ("ea000004:depart:20000.000", ErrorCode.ILLEGAL_VALUE),
             ("ea000005:departs", ErrorCode.WRONG_ARGUMENT_COUNT),
             ("ea000006:appros:400.000,0.000,400.000,0.000,999.000,0.000,10.000", ErrorCode.ILLEGAL_VALUE),
             ("ea000007:move_rel_tool_s:0.000,0.000,x,0.000,0.000,0.000", ErrorCode.ILLEGAL_VALUE),
             ("ea000008:appro:2000.000,0.000,400.000,0.000,180.000,0.000,10.000", ErrorCode.OUT_OF_REACH)]
    for line, code in cases:
        await c.send(line)
        ack = await c.ack()
        assert (ack.id, ack.status, v_code(ack)) == (line[:8], Status.ERROR, code), ack
        assert poses_close(ack.pose, before, tol_mm=0.001, tol_deg=0.001), "an error ack reports the unmoved arm"
    await c.send("ea000009:departs:10.000", "ea00000a:break")
    move, brk = await c.acks(2)
    assert move.ok and brk.ok, "the connection still serves motions"
    await c.close()


async def _send_cli(port: int, *argv: str) -> tuple[int, str, str]:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "aioadept.cli", "send", "--port", str(port), *argv,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    out, err = await proc.communicate()
    return proc.returncode, out.decode(), err.decode()


@pytest.mark.timeout(120)
async def test_aioadept_send_drives_each_line_skill(server, arm):
    A, B = ends(arm)
    code, out, err = await _send_cli(server.port, f"move_to:{wire(A)}", "break", f"move_to_s:{wire(B)}", "break",
                                     "move_rel_tool_s:0,0,-20,0,0,0", "break", f"appro:{wire(A, 30)}", "break",
                                     f"appros:{wire(A, 10)}", "break", "depart:20", "break", "departs:-5", "break")
    assert code == 0, err
    rows = [line.split()[1:3] for line in out.splitlines()]
    assert [s for s, _ in rows] == ["move_to", "break", "move_to_s", "break", "move_rel_tool_s", "break", "appro",
                                    "break", "appros", "break", "depart", "break", "departs", "break"]
    assert all(status == "done" for _, status in rows), out
    end = arm.at(0, -150, 25)
    assert f"pose={end.x:.3f},{end.y:.3f},{end.z:.3f}," in out.splitlines()[-1], "A, 10 + 20 - 5 mm up its tool axis"
    # A bad number is refused by the client before it is sent: one line naming it, no traceback.
    code, out, err = await _send_cli(server.port, "departs:1e9")
    assert code != 0 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
