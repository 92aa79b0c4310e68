"""Security defaults of the simulated controller (docs/security.md), checked over real TCP on 127.0.0.1.

- the listener binds loopback unless told otherwise, and an explicit host exposes it;
- the allow-list and the client limit refuse a connection with one SERVER_BUSY error ack, then close it, and
  nothing such a client sends ever runs;
- motion targets beyond a joint limit or out of reach are refused before any motion (pose unchanged);
- the speed cap (``--max-speed``): no motion runs faster, whatever set_speed and the monitor speed ask for.
"""

from __future__ import annotations

import asyncio

import pytest

from aioadept import Break, MoveJoints, SetSpeed
from aioadept.client import RobotClient
from aioadept.protocol import Status
from aioadept.sim.__main__ import build_parser, options_from_args
from aioadept.sim.controller import Controller
from aioadept.testing.sim import running_sim


# -- the speed cap -------------------------------------------------------------------------------------------

def motion_time_s(ctl: Controller, speed: int, delta_j1: float) -> tuple[float, float]:
    """(duration of a J1 move at program speed ``speed``, highest effective speed seen), with a fake clock."""
    ctl.connect("c")
    t0 = ctl.now_s + 1.0
    j = list(ctl.joints_at(t0))
    j[0] += delta_j1
    out = ctl.handle(f"0000000a:set_speed:{speed}".encode(), "c", t0)
    out += ctl.handle(("0000000b:move_joints:" + ",".join("%.3f" % v for v in j)).encode(), "c", t0)
    out += ctl.handle(b"0000000c:break", "c", t0)
    assert [(o.ack.id, o.ack.status) for o in out] == [("0000000a", Status.DONE), ("0000000b", Status.DONE)]
    peak = ctl.state(t0 + 0.05).speed_pct
    brk = ctl.step(ctl.next_wake_s())[0].ack
    assert brk.id == "0000000c" and brk.status is Status.DONE
    return brk.t_done_s - t0, peak


def test_speed_cap_limits_every_motion_whatever_set_speed_asks():
    free_fast, peak_fast = motion_time_s(Controller(), 100, 60.0)
    free_slow, _ = motion_time_s(Controller(), 10, 60.0)
    capped, peak_capped = motion_time_s(Controller(max_speed_pct=10), 100, 60.0)
    # Asking 100 % under a 10 % cap moves exactly as asking 10 %: several times slower than uncapped.
    assert capped == pytest.approx(free_slow, rel=1e-9)
    assert capped > 5 * free_fast
    assert peak_capped == pytest.approx(10.0) and peak_fast == pytest.approx(100.0)
    # Below the cap nothing changes; the monitor speed still scales, and the cap bounds the product.
    assert motion_time_s(Controller(max_speed_pct=50), 20, 60.0)[0] == pytest.approx(
        motion_time_s(Controller(), 20, 60.0)[0], rel=1e-9)
    assert motion_time_s(Controller(monitor_speed_pct=50, max_speed_pct=25), 100, 60.0)[1] == pytest.approx(25.0)
    with pytest.raises(ValueError):
        Controller(max_speed_pct=0)


def test_max_speed_cli_option():
    parser = build_parser()
    assert options_from_args(parser.parse_args([])).max_speed_pct == 100.0
    assert options_from_args(parser.parse_args(["--max-speed", "15"])).max_speed_pct == 15.0
    with pytest.raises(ValueError):
        options_from_args(parser.parse_args(["--max-speed", "150"]))


@pytest.mark.timeout(20)
async def test_speed_cap_over_tcp():
    # time_scale speeds motions up for the test; the ratio between capped and uncapped durations is what counts.
    durations = {}
    for cap in (100.0, 20.0):
        async with running_sim(time_scale=20, max_speed_pct=cap) as sim, RobotClient(sim.host, sim.port) as robot:
            res = await robot.cmdexec(SetSpeed(100), MoveJoints([45, -90, 180, 0, 90, 0]))
            brk = res.commands[-1].messages[-1].ack
            move = res.commands[-1].messages[0].ack
            durations[cap] = brk.t_done_s - move.t_done_s
            assert sim.controller.joints_deg[0] == pytest.approx(45.0)
    assert durations[20.0] > 3.5 * durations[100.0]
