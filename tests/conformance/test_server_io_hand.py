"""The digital I/O and hand skills (docs/protocol.md) on every backend, over real TCP, with the same assertions:
``signal``, ``sig``, ``wait_sig``, ``open_hand``, ``close_hand``, ``relax_hand``.

Both backends run the one I/O model (aioadept.sim.io): the Python sim through its skill table, the V+ server
(vplus/rsskills.V2) through the emulator's SIGNAL/SIG/OPENI/CLOSEI/RELAXI. The hand is wired as the sim's default
(open valve output 1, close valve output 2, closed-fully switch input 1001) and HAND.TIME is 0.05 s on both
(rsconfig.V2 sets the sim's default). Time bounds are lower bounds (HAND.TIME, a timeout) or generous.
"""

from __future__ import annotations

import pytest

from aioadept.commands import Sig
from aioadept.protocol import ErrorCode, Status
from aioadept.sim.io import HAND_TIME_S

TOL_S = 0.002  # server times are in ms (%.3f): a 0.05 s hold may read 0.049 after rounding both ends


@pytest.mark.timeout(90)
async def test_signal_and_sig(server):
    c = await server.connect()
    await c.send("10000001:sig:3,-3,2001,8", "10000002:signal:3,2001,-8", "10000003:sig:3,-3,2001,8",
                 "10000004:signal:-3", "10000005:sig:3")
    acks = await c.acks(5)
    assert [(a.id, a.status) for a in acks] == [(f"1000000{i}", Status.DONE) for i in range(1, 6)]
    assert acks[0].extra == ("0,-1,0,0",)
    assert acks[2].extra == ("-1,0,-1,0",)
    assert Sig.states(acks[2]) == (True, False, True, False)
    assert acks[4].extra == ("0",)
    await c.close()


@pytest.mark.timeout(90)
async def test_bad_signal_numbers_get_one_error_ack_and_the_connection_stays_usable(server):
    c = await server.connect()
    cases = [("20000001:signal:1001", ErrorCode.ILLEGAL_SIGNAL),       # an input
             ("20000002:signal:4,3000", ErrorCode.ILLEGAL_SIGNAL),     # no such signal (4 must stay off)
             ("20000003:signal:0", ErrorCode.ILLEGAL_SIGNAL),
             ("20000004:sig:513", ErrorCode.ILLEGAL_SIGNAL),
             ("20000005:wait_sig:4,1", ErrorCode.ILLEGAL_SIGNAL),      # an output used as an input
             ("20000006:wait_sig:1001,0", ErrorCode.ILLEGAL_VALUE),    # timeout <= 0
             ("20000007:wait_sig:1001,-1", ErrorCode.ILLEGAL_VALUE),
             ("20000008:signal:2.5", ErrorCode.ILLEGAL_VALUE),
             ("20000009:wait_sig:1001", ErrorCode.WRONG_ARGUMENT_COUNT),
             ("2000000a:close_hand:1", ErrorCode.WRONG_ARGUMENT_COUNT)]
    for line, code in cases:
        await c.send(line)
        ack = await c.ack()
        assert (ack.id, ack.status, ack.error_code) == (line[:8], Status.ERROR, code), (line, ack)
    await c.send("2000000b:sig:4,-1,-2")
    ack = await c.ack()
    assert (ack.status, ack.extra) == (Status.DONE, ("0,-1,-1",)), "a refused command switched a signal"
    await c.close()


@pytest.mark.timeout(90)
async def test_close_hand_acks_no_sooner_than_hand_time_and_reports_closed_on_nothing(server):
    c = await server.connect()
    await c.send("30000001:close_hand", "30000002:wait_sig:1001,5", "30000003:sig:2,-1,1001")
    close, wait, sig = await c.acks(3, timeout=30)
    assert [a.status for a in (close, wait, sig)] == [Status.DONE] * 3, (close, wait, sig)
    assert close.t_done_s - close.t_start_s >= HAND_TIME_S - TOL_S, close
    assert sig.extra == ("-1,-1,-1",), "close valve on, open valve off, closed-fully switch on (nothing gripped)"
    await c.send("30000004:open_hand", "30000005:wait_sig:-1001,5", "30000006:sig:1,-2,-1001")
    opened, wait, sig = await c.acks(3, timeout=30)
    assert [a.status for a in (opened, wait, sig)] == [Status.DONE] * 3
    assert opened.t_done_s - opened.t_start_s >= HAND_TIME_S - TOL_S
    assert sig.extra == ("-1,-1,-1",)
    await c.send("30000007:relax_hand", "30000008:sig:-1,-2")
    relaxed, sig = await c.acks(2, timeout=30)
    assert relaxed.status is Status.DONE and relaxed.t_done_s - relaxed.t_start_s >= HAND_TIME_S - TOL_S
    assert sig.extra == ("-1,-1",), "relaxed: both valves off"
    await c.close()


@pytest.mark.timeout(90)
async def test_hand_acts_only_when_the_arm_is_at_rest(server, arm):
    c = await server.connect()
    await c.send(f"40000001:move_joints:{arm.j1_wire(15)}", "40000002:close_hand",
                 "40000003:here")
    move, close, here = await c.acks(3, timeout=30)
    assert [a.status for a in (move, close, here)] == [Status.DONE] * 3
    # close_hand waited for the motion's end: its ack reports the arm at the target, HAND.TIME after it
    assert close.pose == here.pose and close.t_done_s - move.t_done_s > 0.1
    await c.close()


@pytest.mark.timeout(90)
async def test_wait_sig_times_out_with_an_error_ack_and_soft_signals_wake_it(server):
    c = await server.connect()
    await c.send("50000001:wait_sig:1002,0.3")
    ack = await c.ack(timeout=30)
    assert (ack.status, ack.error_code) == (Status.ERROR, ErrorCode.SIGNAL_TIMEOUT)
    assert ack.t_done_s - ack.t_start_s >= 0.3 - TOL_S
    await c.send("50000002:signal:2005", "50000003:wait_sig:2005,5", "50000004:wait_sig:-2006,5")
    acks = await c.acks(3, timeout=30)
    assert [a.status for a in acks] == [Status.DONE] * 3
    assert all(a.t_done_s - a.t_start_s < 0.5 for a in acks[1:]), "a wait for a signal already set returns at once"
    await c.close()


@pytest.mark.timeout(90)
async def test_stop_aborts_a_waiting_wait_sig(server):
    c = await server.connect()
    await c.send("60000000:sig:1", "60000001:wait_sig:1003,60")   # one write: both lines are read together
    assert (await c.ack()).id == "60000000"         # so the wait is running or queued now: a stop aborts either
    s = await server.connect()
    await s.send("60000003:stop")
    stop = await s.ack(timeout=30)
    wait = await c.ack(timeout=30)
    assert (wait.id, wait.status) == ("60000001", Status.ABORTED)
    assert (stop.id, stop.status) == ("60000003", Status.DONE)
    await c.close()
    await s.close()


@pytest.mark.timeout(90)
async def test_hand_wiring_is_the_controllers_configuration(backend, start_server):
    """``aioadept sim --hand OPEN,CLOSE,SWITCH``: the hand skills drive those signals on both backends (the V+
    server through OPENI/CLOSEI, which use the controller's configuration, as on a real controller)."""
    async with start_server(backend, "--hand", "5,6,1010,0.1") as srv:
        c = await srv.connect()
        await c.send("70000001:close_hand", "70000002:wait_sig:1010,5", "70000003:sig:6,-5,-1,-2,-1001")
        acks = await c.acks(3, timeout=30)
        assert [a.status for a in acks] == [Status.DONE] * 3, acks
        assert acks[2].extra == ("-1,-1,-1,-1,-1",)
        await c.close()


@pytest.mark.timeout(90)
async def test_state_stream_sends_each_signal_change_once_with_its_time(backend, start_server):
    """Both backends publish the one I/O model's changes on ``robot.state`` (the V+ server's SIGNAL and CLOSEI
    included), each once, in order, with the server time it happened."""
    import asyncio

    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.pubsub import Subscriber

    async with start_server(backend, "--state-endpoint", "tcp://127.0.0.1:0", "--state-rate-hz", "100") as srv:
        log = srv.log.read_text()
        endpoint = next(f.split("=", 1)[1] for ln in log.splitlines() if ln.startswith("READY")
                        for f in ln.split() if f.startswith("state="))
        async with Subscriber(endpoint, topics=[ROBOT_STATE_TOPIC]) as sub:
            await asyncio.wait_for(sub.recv(), 10)          # subscribed
            c = await srv.connect()
            await c.send("80000001:signal:7,2003", "80000002:close_hand", "80000003:wait_sig:1001,5",
                         "80000004:signal:-7")
            acks = await c.acks(4, timeout=30)
            assert [a.status for a in acks] == [Status.DONE] * 4
            seen, times = [], []
            while (7, False) not in seen:
                st = RobotState.from_bytes((await asyncio.wait_for(sub.recv(), 10))[1])
                seen += [(e.signal, e.on) for e in st.changes]
                times += [e.t_s for e in st.changes]
            assert seen == [(7, True), (2003, True), (2, True), (1001, True), (7, False)]
            assert times == sorted(times) and times[0] >= acks[0].t_start_s - 0.002
            while st.hand != "closed" or 7 in st.outputs_on:
                st = RobotState.from_bytes((await asyncio.wait_for(sub.recv(), 10))[1])
            assert (st.outputs_on, st.inputs_on, st.soft_on) == ((2,), (1001,), (2003,))
            await c.close()
