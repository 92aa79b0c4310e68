"""After a stop, nothing actuates (docs/security.md, "Safety promises"), on every backend, over real TCP.

A hand skill or an output queued behind a motion waits for it (the hand's ``BREAK``, a second motion waiting for
its turn). A stop read meanwhile brakes the motion, and the wait ends: the skill must then return without
switching anything, and be acked ``aborted``. The V+ server (vplus/rsskills.V2) checks for the stop right before
each actuation (``rs.chkstop``); both of its hand wirings are run: ``OPENI``/``CLOSEI``/``RELAXI`` (the default)
and plain ``SIGNAL`` outputs (``rs.hsig = TRUE``). The valves and outputs are read back with ``sig`` right after
the stop's ``done`` and again once HAND.TIME has passed several times over, and the same skill then acts normally.
"""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from aioadept.protocol import Status
from aioadept.sim.io import HAND_TIME_S

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
SETTLE_S = 6 * HAND_TIME_S   # long past the moment a hand skill that got through would have switched
ACTED = {"open_hand": "-1,0", "close_hand": "0,-1", "relax_hand": "0,0"}  # sig:1,2 once the skill has acted


def slow_move(arm) -> tuple[str, str]:
    """J1 turns 150 deg (a Cobra's 100) at 10 % of the s850's rate: seconds."""
    return f"set_speed:{arm.speed(10)}", f"move_joints:{arm.j1_wire(150)}"


def _signal_wired_hand(tmp_path: Path) -> tuple[str, ...]:
    """``aioadept sim`` options that load the shipped V+ server with ``rs.hsig = TRUE`` in its configuration:
    the hand skills switch the valve outputs with SIGNAL. The later ``--vplus`` replaces the fixture's list."""
    cfg = (VPLUS / "rsconfig.V2").read_text()
    assert cfg.count("rs.hsig = FALSE") == 1
    (tmp_path / "rsconfig.V2").write_text(cfg.replace("rs.hsig = FALSE", "rs.hsig = TRUE"))
    return ("--vplus", str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(tmp_path / "rsconfig.V2"))


async def _stop_from_another_connection(server, stop_id: str):
    s = await server.connect()
    await s.send(f"{stop_id}:stop")
    return s, await s.ack(timeout=30)


@pytest.mark.timeout(90)
@pytest.mark.parametrize("backend,wiring", [("python", "config"), ("vplus", "config"), ("vplus", "signal")])
@pytest.mark.parametrize("setup,skill,valves", [
    (None, "close_hand", "0,0"),              # relaxed: both valves (outputs 1 open, 2 close) stay off
    (None, "open_hand", "0,0"),
    ("close_hand", "relax_hand", "0,-1"),     # closed: the close valve stays on
])
async def test_a_hand_skill_waiting_for_a_motion_when_a_stop_comes_never_switches_the_valves(
        backend, wiring, setup, skill, valves, start_server, tmp_path, arm):
    extra = _signal_wired_hand(tmp_path) if wiring == "signal" else ()
    async with start_server(backend, *extra) as server:
        c = await server.connect()
        if setup:
            await c.send(f"a0000000:{setup}")
            assert (await c.ack(timeout=30)).status is Status.DONE
        await c.send(f"a0000001:{slow_move(arm)[0]}", f"a0000002:{slow_move(arm)[1]}", f"a0000003:{skill}")
        speed, move = await c.acks(2)
        assert speed.ok and move.ok, (speed, move)
        await asyncio.sleep(0.3)                  # the hand skill waits for the arm to be at rest
        s, stop = await _stop_from_another_connection(server, "a0000004")
        hand = await c.ack(timeout=30)
        assert (hand.id, hand.status) == ("a0000003", Status.ABORTED), hand
        assert stop.status is Status.DONE, stop
        await s.send("a0000005:sig:1,2")
        assert (await s.ack()).extra == (valves,), f"{skill} switched the valves after the stop"
        await asyncio.sleep(SETTLE_S)
        await s.send("a0000006:sig:1,2")
        assert (await s.ack()).extra == (valves,), f"{skill} switched the valves after the stop"
        # The stop is over: the same skill, sent again, acts.
        await c.send(f"a0000007:{skill}", "a0000008:sig:1,2")
        again, sig = await c.acks(2, timeout=30)
        assert (again.status, sig.extra) == (Status.DONE, (ACTED[skill],)), (again, sig)
        await c.close()
        await s.close()


@pytest.mark.timeout(90)
@pytest.mark.parametrize("command,outputs", [("signal:5,2007", "5,2007"), ("enable_air", "8")])
async def test_an_output_queued_behind_a_motion_never_switches_after_a_stop(server, command, outputs, arm):
    """The output waits behind a second motion, which waits for its turn behind the slow one."""
    c = await server.connect()
    await c.send(f"b0000001:{slow_move(arm)[0]}", f"b0000002:{slow_move(arm)[1]}",
                 f"b0000003:move_joints:{arm.home_wire}",
                 f"b0000004:{command}")
    speed, move = await c.acks(2)
    assert speed.ok and move.ok, (speed, move)
    await asyncio.sleep(0.3)
    s, stop = await _stop_from_another_connection(server, "b0000005")
    second, out = await c.acks(2, timeout=30)
    assert [(a.id, a.status) for a in (second, out)] == [("b0000003", Status.ABORTED), ("b0000004", Status.ABORTED)]
    assert stop.status is Status.DONE, stop
    off = ",".join("0" for _ in outputs.split(","))
    for _ in range(2):
        await s.send(f"b0000006:sig:{outputs}")
        assert (await s.ack()).extra == (off,), f"{command} switched an output after the stop"
        await asyncio.sleep(SETTLE_S)
    await c.close()
    await s.close()
