"""The server-side safety promises (docs/security.md, "Safety promises of the robot server"), on every backend.

Each test runs against the Python sim and against the shipped V+ server on the emulator (conftest.py, fixture
``server``), over real TCP with raw lines, so the server is checked and not a client's politeness. The Python
sim kept these promises first (tests/integration/test_safety_sim.py); these tests hold the V+ server
(vplus/rserver.V2) to the same ones. Timing is never asserted finer than "before the other client's break has
been answered": the order of events, not milliseconds.
"""

from __future__ import annotations

import asyncio

import pytest

from aioadept.geometry import poses_close
from aioadept.protocol import NO_ID, ErrorCode, Status
from aioadept.protocol.robotstatus import parse_status_fields


# -- item 1: read-only queries from an idle connection are answered by the reader at once ----------------------

@pytest.mark.timeout(90)
async def test_here_hello_and_status_from_an_idle_connection_are_answered_while_another_clients_break_waits(
        server, arm):
    mover = await server.connect()
    poller = await server.connect()
    # J1 turns 150 deg at 10 %: about 6 s, during which the mover's break waits (and, in V+, holds task 1).
    await mover.send(f"aaaa0001:set_speed:{arm.speed(10)}", f"aaaa0002:move_joints:{arm.j1_wire(150)}",
                     "aaaa0003:break")
    speed, move = await mover.acks(2)
    assert speed.ok and move.ok
    brk = asyncio.create_task(mover.ack(30))
    try:
        await poller.send("bbbb0001:here", "bbbb0002:hello", "bbbb0003:status")
        here, hello, status = await poller.acks(3, timeout=30)
        assert not brk.done(), "here, hello and status were answered while the other client's break still waited"
    finally:
        brk_ack = await brk
    assert (here.id, here.status) == ("bbbb0001", Status.DONE)
    assert (hello.id, hello.status) == ("bbbb0002", Status.DONE)
    assert hello.extra[0] == "1", "protocol version 1"
    assert (status.id, status.status) == ("bbbb0003", Status.DONE)
    st = parse_status_fields(status.extra)
    assert st.moving and st.error_code == 0 and st.power and not st.estop, status.extra  # the mover's arm
    assert (brk_ack.id, brk_ack.status) == ("aaaa0003", Status.DONE)
    assert max(here.t_done_s, hello.t_done_s, status.t_done_s) <= brk_ack.t_done_s
    assert not poses_close(here.pose, arm.pose(arm.j1(150)), tol_mm=1.0, tol_deg=1.0), \
        "the pose is the current one, not the target's"
    await mover.close()
    await poller.close()


@pytest.mark.timeout(90)
async def test_here_behind_the_same_connections_own_commands_keeps_its_order(server, arm):
    c = await server.connect()
    # here with commands of its own connection pending runs in turn: after the break, at the target.
    await c.send(f"cccc0001:set_speed:{arm.speed(20)}", f"cccc0002:move_joints:{arm.j1_wire(60)}", "cccc0003:break",
                 "cccc0004:here", "cccc0005:hello")
    acks = await c.acks(5, timeout=30)
    assert [a.id for a in acks] == ["cccc0001", "cccc0002", "cccc0003", "cccc0004", "cccc0005"]
    assert all(a.ok for a in acks), acks
    assert poses_close(acks[3].pose, arm.pose(arm.j1(60)), tol_mm=0.05, tol_deg=0.05), \
        "here came after the break: the arm is at the target"
    await c.close()


# -- item 2: the reserved ID ------------------------------------------------------------------------------------

@pytest.mark.timeout(90)
async def test_the_reserved_id_is_refused_and_nothing_runs(server, arm):
    c = await server.connect()
    await c.send(f"00000000:move_joints:{arm.j1_wire(30)}", "00000000:here", "dddd0001:break", "dddd0002:here")
    move, here0, brk, here = await c.acks(4, timeout=30)
    for ack in (move, here0):
        assert (ack.id, ack.status, ack.error_code) == (NO_ID, Status.ERROR, ErrorCode.MALFORMED_MESSAGE), ack
    assert brk.ok and here.ok
    assert poses_close(here.pose, arm.home_pose, tol_mm=0.01, tol_deg=0.01), "the refused move never ran"
    await c.close()


# -- item 3: an ID still pending on the same connection --------------------------------------------------------

@pytest.mark.timeout(90)
async def test_a_duplicate_pending_id_answers_an_error_at_once_and_nothing_hangs(server, arm):
    c = await server.connect()
    # J1 to 60 at 10 %: the break waits a few seconds; the second eeee0003 comes while it is pending.
    await c.send(f"eeee0001:set_speed:{arm.speed(10)}", f"eeee0002:move_joints:{arm.j1_wire(60)}")
    speed, move = await c.acks(2)
    assert speed.ok and move.ok
    await c.send("eeee0003:break", f"eeee0003:move_joints:{arm.j1_wire(-60)}")
    dup, brk = await c.acks(2, timeout=30)
    assert (dup.id, dup.status, dup.error_code) == ("eeee0003", Status.ERROR, ErrorCode.MALFORMED_MESSAGE), \
        "the duplicate is refused at once, before the pending break is answered"
    assert (brk.id, brk.status) == ("eeee0003", Status.DONE)
    assert poses_close(brk.pose, arm.pose(arm.j1(60)), tol_mm=0.05, tol_deg=0.05)
    # The ID is free again once answered, and the refused move never ran.
    await c.send("eeee0003:here")
    here = await c.ack()
    assert here.ok and poses_close(here.pose, arm.pose(arm.j1(60)), tol_mm=0.05, tol_deg=0.05)
    await c.close()


@pytest.mark.timeout(90)
async def test_a_stop_is_never_refused_for_a_duplicate_id(server, arm):
    c = await server.connect()
    await c.send(f"kkkk0001:set_speed:{arm.speed(10)}", f"kkkk0002:move_joints:{arm.j1_wire(150)}")
    assert all(a.ok for a in await c.acks(2))
    # kkkk0003 is pending (the break waits for the motion); a stop with the same ID is still served.
    await c.send("kkkk0003:break", "kkkk0003:stop")
    brk, stop = await c.acks(2, timeout=30)
    assert [(a.id, a.status) for a in (brk, stop)] == [("kkkk0003", Status.ABORTED), ("kkkk0003", Status.DONE)]
    assert stop.t_done_s - brk.t_start_s < 4.0, "the stop did not wait for the motion to complete"
    await c.close()


# -- item 4: a stop never aborts a stop -------------------------------------------------------------------------

@pytest.mark.timeout(90)
async def test_three_stops_in_a_row_each_get_done(server, arm):
    c = await server.connect()
    await c.send(f"ffff0001:set_speed:{arm.speed(10)}", f"ffff0002:move_joints:{arm.j1_wire(150)}", "ffff0003:break")
    speed, move = await c.acks(2)
    assert speed.ok and move.ok
    await c.send("ffff0004:stop", "ffff0005:stop", "ffff0006:stop")
    acks = {a.id: a for a in await c.acks(4, timeout=30)}
    assert acks["ffff0003"].status is Status.ABORTED, "the waiting break is aborted"
    stops = [acks[i] for i in ("ffff0004", "ffff0005", "ffff0006")]
    assert [s.status for s in stops] == [Status.DONE] * 3, stops
    assert all(poses_close(s.pose, stops[0].pose, tol_mm=0.01, tol_deg=0.01) for s in stops), \
        "all at the same rest pose"
    # And with the arm at rest, three stops in one write: each done, the connection still serves.
    await c.send("ffff0007:stop", "ffff0008:stop", "ffff0009:stop", "ffff0010:here")
    acks = await c.acks(4)
    assert [(a.id, a.status) for a in acks] == [("ffff0007", Status.DONE), ("ffff0008", Status.DONE),
                                                ("ffff0009", Status.DONE), ("ffff0010", Status.DONE)], acks
    await c.close()


# -- item 5: numbers outside the grammar, absurd magnitudes ----------------------------------------------------

def bad_values(arm) -> list[tuple[str, ErrorCode]]:
    """Numbers outside the grammar or absurd, each refused before anything moves (the joint ones on the arm's own
    joints: J1 and its last joint)."""
    return [*BAD_NUMBERS,
            (f"gggg0016:move_joints:{arm.wire(arm.with_joint(0, 3601))}", ErrorCode.ILLEGAL_VALUE),
            (f"gggg0017:move_rel_joints:{arm.rel_last(-1000000)}", ErrorCode.ILLEGAL_VALUE)]


BAD_NUMBERS = [
    ("gggg0001:set_speed:0.001", ErrorCode.ILLEGAL_VALUE),
    ("gggg0002:set_speed:0." + "0" * 20 + "1", ErrorCode.ILLEGAL_VALUE),
    ("gggg0003:set_speed:1e308", ErrorCode.ILLEGAL_VALUE),
    ("gggg0004:set_speed:1_0", ErrorCode.ILLEGAL_VALUE),
    ("gggg0005:set_speed:inf", ErrorCode.ILLEGAL_VALUE),
    ("gggg0006:set_speed:\t10", ErrorCode.ILLEGAL_VALUE),
    ("gggg0007:set_speed:1\x070", ErrorCode.ILLEGAL_VALUE),
    ("gggg0008:set_speed:1 0", ErrorCode.ILLEGAL_VALUE),
    ("gggg0009:set_speed:nan", ErrorCode.ILLEGAL_VALUE),
    ("gggg0010:set_speed:" + "0" * 24 + "1", ErrorCode.ILLEGAL_VALUE),  # 25 characters, value 1
    ("gggg0011:move_to:480,0,500,0,180,100000000000000000000", ErrorCode.ILLEGAL_VALUE),
    ("gggg0012:move_to:480,0,500,0,180,720", ErrorCode.ILLEGAL_VALUE),
    ("gggg0013:move_to:20000,0,500,0,180,0", ErrorCode.ILLEGAL_VALUE),
    ("gggg0014:move_rel_world:0,0,0,0,0,720", ErrorCode.ILLEGAL_VALUE),
    ("gggg0015:move_rel_tool:0,0,-10001,0,0,0", ErrorCode.ILLEGAL_VALUE),
]


@pytest.mark.timeout(120)
async def test_bad_values_answer_error_acks_and_nothing_moves(server, arm):
    c = await server.connect()
    await c.send("gggg0000:here")
    home = (await c.ack()).pose
    for k, (line, code) in enumerate(bad_values(arm)):
        await c.send(line)
        ack = await c.ack()
        assert (ack.id, ack.status, ack.error_code) == (line[:8], Status.ERROR, code), (line, ack)
        await c.send("hhhh%04d:break" % k, "iiii%04d:here" % k)
        brk, here = await c.acks(2)
        assert brk.ok and here.ok, "the connection stays usable"
        assert poses_close(here.pose, home, tol_mm=0.01, tol_deg=0.01), (line, "nothing moved")
    await c.close()


@pytest.mark.timeout(90)
async def test_numbers_of_the_grammar_within_the_limits_are_accepted(server, arm):
    c = await server.connect()
    ok = ["jjjj0001:set_speed:+50", "jjjj0002:set_speed:050", "jjjj0003:move_rel_world:0,0,.5,0,0,-0.",
          "jjjj0004:break", f"jjjj0005:move_rel_joints:{arm.rel_last(-10)}", "jjjj0006:break",
          "jjjj0007:set_speed:" + "0" * 21 + "100"]  # 24 characters: the longest accepted
    await c.send(*ok)
    acks = await c.acks(len(ok), timeout=30)
    assert [a.id for a in acks] == [ln[:8] for ln in ok]
    assert all(a.ok for a in acks), acks
    await c.close()
