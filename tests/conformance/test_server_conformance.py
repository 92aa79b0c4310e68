"""RobotServer behaviour that every backend must show (docs/protocol.md), over real TCP.

Each test runs against the Python sim and against the shipped V+ server on the emulator (conftest.py), on the
robot model's arm (fixture ``arm``: joints, poses and speeds from the model); the tests marked for ``any_server``
also run against the AdeptServer-style V+ example. Timing bounds are generous (the machine is shared): they tell
"at once" from "after a motion of seconds", nothing finer.
"""

from __future__ import annotations

import asyncio
import re

import pytest

from aioadept.geometry import poses_close
from aioadept.protocol import ErrorCode, Status, parse_ack

ACK_RE = re.compile(rb"^[0-9A-Za-z]{8}:(done|error|aborted):\d+\.\d{3},\d+\.\d{3}:"
                    rb"(-?\d+\.\d{3},){5}-?\d+\.\d{3}(:[^:\r\n]*)*\r\n$")


@pytest.mark.timeout(90)
async def test_hello_and_here(server, arm):
    c = await server.connect()
    await c.send("aaaa0001:hello", "aaaa0002:here")
    hello, here = await c.acks(2)
    assert (hello.id, hello.status) == ("aaaa0001", Status.DONE)
    assert hello.extra[0] == "1", "protocol version 1"
    assert len(hello.extra) >= 2 and hello.extra[1], "the server names itself"
    assert (here.id, here.status) == ("aaaa0002", Status.DONE)
    assert poses_close(here.pose, arm.home_pose, tol_mm=0.01, tol_deg=0.01), "the sim starts at home"
    await c.close()


@pytest.mark.adeptserver
@pytest.mark.timeout(90)
async def test_ack_grammar_of_motion_skills(any_server, arm):
    c = await any_server.connect()
    target = arm.at(0, 100, 100)
    lines = [f"bbbb0001:move_joints:{arm.j1_wire(10)}", "bbbb0002:break",
             f"bbbb0003:move_to:{arm.pose_wire(target)}", "bbbb0004:break",
             "bbbb0005:set_speed:50", "bbbb0006:move_rel_world:0.000,0.000,-20.000,0.000,0.000,0.000",
             "bbbb0007:break"]
    await c.send(*lines)
    raws = [await c.raw(30) for _ in lines]
    for sent, raw in zip(lines, raws, strict=True):
        assert ACK_RE.match(raw), raw
        assert raw.startswith(sent[:8].encode() + b":done:"), (sent, raw)
    acks = [parse_ack(r[:-2]) for r in raws]
    times = [t for a in acks for t in (a.t_start_s, a.t_done_s)]
    assert times == sorted(times), "server times never go back"
    assert poses_close(acks[3].pose, target, tol_mm=0.01, tol_deg=0.01)
    assert poses_close(acks[6].pose, arm.at(0, 100, 80), tol_mm=0.01, tol_deg=0.01)
    await c.close()


@pytest.mark.timeout(90)
async def test_error_acks_without_motion(server):
    c = await server.connect()
    await c.send("cccc0001:here")
    before = (await c.ack()).pose
    cases = [("cccc0002:fly", ErrorCode.UNKNOWN_SKILL),
             ("cccc0003:move_to:1.000", ErrorCode.WRONG_ARGUMENT_COUNT),
             ("cccc0004:set_speed:101", ErrorCode.ILLEGAL_VALUE),
             ("cccc0009:set_speed:0", ErrorCode.ILLEGAL_VALUE),
             ("cccc0005:move_to:1,2,x,4,5,6", ErrorCode.ILLEGAL_VALUE),
             ("cccc0006:move_to:2000.000,0.000,500.000,0.000,180.000,0.000", ErrorCode.OUT_OF_REACH)]
    for line, code in cases:
        await c.send(line)
        ack = await c.ack()
        assert (ack.id, ack.status, ack.error_code) == (line[:8], Status.ERROR, code), ack
        assert ack.pose == before, "an error ack reports the unmoved arm"
    await c.send("garbage line", "cccc0007:break", "cccc0008:here")
    bad, brk, here = await c.acks(3)
    assert (bad.id, bad.status, bad.error_code) == ("00000000", Status.ERROR, ErrorCode.MALFORMED_MESSAGE)
    assert brk.ok and here.ok and here.pose == before, "nothing moved, and the connection still serves"
    await c.close()


@pytest.mark.timeout(90)
async def test_stop_during_break_from_another_connection(server, arm):
    a = await server.connect()
    b = await server.connect()
    # J1 turns 150 deg at 10 % (on a Cobra 100 deg): seconds, so the stop surely comes while the break waits.
    await a.send(f"dddd0001:set_speed:{arm.speed(10)}", f"dddd0002:move_joints:{arm.j1_wire(150)}", "dddd0003:break")
    speed, move = await a.acks(2)
    assert speed.ok and move.ok
    await asyncio.sleep(0.3)  # the arm is moving now; the break is waiting (not a readiness wait)
    await b.send("eeee0001:stop")
    brk = await a.ack(20)
    stop = await b.ack(20)
    assert (brk.id, brk.status) == ("dddd0003", Status.ABORTED)
    assert (stop.id, stop.status) == ("eeee0001", Status.DONE)
    assert stop.t_done_s >= brk.t_done_s, "the stop is done when the arm is at rest, after the abort"
    assert stop.t_done_s - move.t_done_s < 4.0, "the stop did not wait for the motion to complete"
    await b.send("eeee0002:here")
    at_rest = (await b.ack()).pose
    assert not poses_close(at_rest, arm.pose(arm.j1(150)), tol_mm=1.0, tol_deg=1.0), "stopped short"
    await asyncio.sleep(0.5)
    await b.send("eeee0003:here")
    assert poses_close((await b.ack()).pose, at_rest, tol_mm=0.01, tol_deg=0.01), "and it stays at rest"
    await a.send("dddd0004:here")
    assert (await a.ack()).ok, "the stopped client's connection still serves"
    await a.close()
    await b.close()


@pytest.mark.timeout(90)
async def test_disconnect_drops_that_clients_queued_commands(server, arm):
    a = await server.connect()
    # J1 to 90 at 20 %: about 2 s. Then a move back home that must never run: A is gone by then.
    await a.send(f"ffff0001:set_speed:{arm.speed(20)}", f"ffff0002:move_joints:{arm.j1_wire(90)}", "ffff0003:break",
                 f"ffff0004:move_joints:{arm.home_wire}", "ffff0005:break")
    assert all(x.ok for x in await a.acks(2))
    await a.close()
    b = await server.connect()
    # B's break runs after everything A queued before it (one executor, arrival order), had it been kept.
    await b.send("gggg0001:break", "gggg0002:here")
    brk, here = await b.acks(2, timeout=30)
    assert brk.ok and here.ok
    assert poses_close(here.pose, arm.pose(arm.j1(90)), tol_mm=0.05, tol_deg=0.05), \
        "the first motion completed and the dropped move home never ran"
    await b.close()


@pytest.mark.adeptserver
@pytest.mark.timeout(90)
async def test_pipelining_ten_commands_in_one_write(any_server, arm):
    c = await any_server.connect()
    lines = ["hhhh0001:set_speed:50", f"hhhh0002:move_joints:{arm.j1_wire(20)}",
             f"hhhh0003:move_joints:{arm.j1_wire(-20)}", "hhhh0004:break", "hhhh0005:enable_air",
             "hhhh0006:disable_air", f"hhhh0007:move_rel_joints:{arm.rel_last(10)}", "hhhh0008:break",
             "hhhh0009:set_speed:100", f"hhhh0010:move_joints:{arm.home_wire}"]
    await c.send(*lines)
    acks = await c.acks(10, timeout=30)
    assert [a.id for a in acks] == [ln[:8] for ln in lines], "one ack per command, in order"
    assert all(a.status is Status.DONE for a in acks), acks
    q = arm.j1(-20)
    assert poses_close(acks[7].pose, arm.pose(arm.with_last(q[arm.last] + 10, q)), tol_mm=0.05, tol_deg=0.05)
    await c.close()


@pytest.mark.timeout(90)
async def test_oversize_line_gets_an_error_and_the_connection_stays_usable(server, arm):
    c = await server.connect()
    await c.send(b"iiii0001:move_to:" + b"9" * 200, "iiii0002:here")
    big, here = await c.acks(2)
    assert (big.id, big.status, big.error_code) == ("iiii0001", Status.ERROR, ErrorCode.LINE_TOO_LONG)
    assert here.ok and poses_close(here.pose, arm.home_pose, tol_mm=0.01, tol_deg=0.01), "nothing moved"
    await c.close()


@pytest.mark.timeout(90)
async def test_forward_processing_is_one_motion_deep(server, arm):
    c = await server.connect()
    # a: J1 0 -> 90 at 20 % (about 1.9 s); b: back at 20 % (the same).
    await c.send(f"jjjj0001:set_speed:{arm.speed(20)}", f"jjjj0002:move_joints:{arm.j1_wire(90)}",
                 f"jjjj0003:set_speed:{arm.speed(20)}", f"jjjj0004:move_joints:{arm.home_wire}", "jjjj0005:break")
    _, a, _, b, brk = await c.acks(5, timeout=30)
    assert a.ok and b.ok and brk.ok
    assert a.t_done_s - a.t_start_s < 0.5, "move a acks as soon as its motion has started"
    assert 1.2 <= b.t_done_s - a.t_done_s <= 3.5, "move b acks only when a is (nearly) complete"
    assert 1.2 <= brk.t_done_s - b.t_done_s <= 3.5, "break acks when b has completed"
    assert poses_close(brk.pose, arm.home_pose, tol_mm=0.05, tol_deg=0.05)
    await c.close()


@pytest.mark.timeout(90)
async def test_stop_with_nothing_to_abort_is_done_at_once_and_the_server_goes_on(server, arm):
    c = await server.connect()
    await c.send("kkkk0001:stop")
    stop = await c.ack()
    assert (stop.id, stop.status) == ("kkkk0001", Status.DONE)
    assert stop.t_done_s - stop.t_start_s < 0.5
    assert poses_close(stop.pose, arm.home_pose, tol_mm=0.01, tol_deg=0.01)
    await c.send(f"kkkk0002:move_joints:{arm.j1_wire(5)}", "kkkk0003:break")
    move, brk = await c.acks(2)
    assert move.ok and brk.ok, "commands after a stop execute normally"
    assert poses_close(brk.pose, arm.pose(arm.j1(5)), tol_mm=0.05, tol_deg=0.05)
    await c.close()
