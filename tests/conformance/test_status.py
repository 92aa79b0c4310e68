"""The ``status`` extension skill (docs/protocol.md, section 4.7) on every backend, over real TCP: the same
assertions against the Python sim and the shipped V+ server on the emulator (conftest.py)."""

from __future__ import annotations

import pytest

from aioadept.client import RobotClient
from aioadept.commands import GetStatus, MoveJoints, SetSpeed
from aioadept.protocol import Status
from aioadept.protocol.robotstatus import RobotStatus, parse_status_fields

SIM_TIME_SCALE = {"python": 1.0}
"""The time scale each backend's status reports (ts=): the Python sim its own; the V+ server none."""


@pytest.mark.timeout(90)
async def test_status_at_rest_then_moving_then_at_rest(server, arm):
    c = await server.connect()
    await c.send("cccc0001:status")
    idle = await c.ack()
    assert (idle.id, idle.status) == ("cccc0001", Status.DONE)
    assert idle.extra[0].startswith("mv=0,sp=100,er=0,"), idle.extra
    assert parse_status_fields(idle.extra) == RobotStatus(moving=False, speed_pct=100.0, error_code=0,
                                                          error_text="", power=True, estop=False, hand="relaxed",
                                                          time_scale=SIM_TIME_SCALE.get(server.backend))
    # a long joint move: forward processing acks it as it starts; status then finds the arm moving
    await c.send(f"cccc0002:set_speed:{arm.speed(10)}", f"cccc0003:move_joints:{arm.j1_wire(60)}",
                 "cccc0004:status")
    _, move, moving = await c.acks(3)
    assert move.status is Status.DONE and moving.status is Status.DONE
    st = parse_status_fields(moving.extra)
    assert st.moving and st.error_code == 0 and st.power and not st.estop
    assert moving.t_done_s - move.t_start_s < 1.0, "answered while the move runs, not after it"
    await c.send("cccc0005:stop")
    await c.ack()
    await c.send("cccc0006:status")
    rest = parse_status_fields((await c.ack()).extra)
    assert not rest.moving
    await c.close()


@pytest.mark.timeout(90)
async def test_client_status_and_the_command(server, arm):
    async with RobotClient(server.host, server.port) as robot:
        st = await robot.status()
        assert (st.moving, st.speed_pct, st.error_code, st.power, st.estop) == (False, 100.0, 0, True, False)
        res = await robot.cmdexec(SetSpeed(arm.speed(10)), MoveJoints(arm.six(arm.j1(60)), break_move=False),
                                  GetStatus())
        assert res.messages[-1].skill == "status"
        assert parse_status_fields(res.messages[-1].ack.extra).moving
        await robot.stop()


@pytest.mark.timeout(90)
async def test_aioadept_send_status_prints_the_fields(server):
    import asyncio
    import sys

    proc = await asyncio.create_subprocess_exec(sys.executable, "-m", "aioadept", "send", "--host", server.host,
                                                "--port", str(server.port), "status",
                                                stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    out, err = await asyncio.wait_for(proc.communicate(), 60)
    assert proc.returncode == 0, err
    (line,) = out.decode().splitlines()
    ts = ",ts=1" if server.backend in SIM_TIME_SCALE else ""
    assert " status " in line and " done " in line and line.endswith(f" mv=0,sp=100,er=0,pw=1,es=0,hd=r{ts}"), line


@pytest.mark.timeout(90)
async def test_status_reports_the_hand_as_its_valves_command_it(server):
    """hd= follows open_hand, close_hand and relax_hand, and signal on the valve outputs (1 open, 2 close: both
    servers' defaults), including the fault of both valves on."""
    c = await server.connect()
    seen = []
    for i, line in enumerate(("close_hand", "open_hand", "relax_hand", "signal:1,2", "signal:-1,-2")):
        await c.send(f"cccd{i:04d}:{line}", f"ccce{i:04d}:status")
        act, st = await c.acks(2)
        assert act.status is Status.DONE and st.status is Status.DONE, (act, st)
        seen.append(parse_status_fields(st.extra).hand)
    assert seen == ["closed", "open", "relaxed", "both", "relaxed"]
    await c.close()
