"""RobotClient refuses bad values at its API with ValueError before anything is sent, and never issues the reserved
ID 00000000 nor an ID still pending or given up on its connection (client side). No sockets: the
scripted server runs over the in-memory stream pair.
"""

from __future__ import annotations

import asyncio
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept import Break, Here, MoveToolZ, SetSpeed, Skill
from aioadept.client import RobotClient
from aioadept.cli.send import main as send_main
from aioadept.errors import AckTimeout
from aioadept.protocol import NO_ID
from aioadept.testing import Reply, ScriptedServer

BAD_TIMEOUTS = [math.nan, math.inf, -math.inf, -1.0, 0, 0.0, -1e-9, True, "1", [1]]


# ------------------------------------------------------------------------------------------ constructor
@pytest.mark.parametrize("bad", BAD_TIMEOUTS)
def test_bad_timeouts_in_the_constructor_and_setters_are_value_errors(bad):
    with pytest.raises(ValueError, match="^ack_timeout_s"):
        RobotClient(ack_timeout_s=bad)
    with pytest.raises(ValueError, match="^connect_timeout_s"):
        RobotClient(connect_timeout_s=bad)
    robot = RobotClient()
    with pytest.raises(ValueError, match="^ack_timeout_s"):
        robot.ack_timeout_s = bad
    with pytest.raises(ValueError, match="^connect_timeout_s"):
        robot.connect_timeout_s = bad
    assert robot.ack_timeout_s == 60.0 and robot.connect_timeout_s == 5.0


def test_none_means_forever_only_for_acks():
    assert RobotClient(ack_timeout_s=None).ack_timeout_s is None
    with pytest.raises(ValueError, match="^connect_timeout_s"):
        RobotClient(connect_timeout_s=None)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="^stop_timeout_s"):
        RobotClient(stop_timeout_s=None)  # type: ignore[arg-type]


@pytest.mark.parametrize("bad", BAD_TIMEOUTS)
def test_bad_stop_timeouts_are_value_errors_and_the_default_is_short(bad):
    with pytest.raises(ValueError, match="^stop_timeout_s"):
        RobotClient(stop_timeout_s=bad)
    robot = RobotClient()
    with pytest.raises(ValueError, match="^stop_timeout_s"):
        robot.stop_timeout_s = bad
    # a stop is acked at rest, a deceleration ramp away: its default limit is seconds, not ack_timeout_s's minute
    assert robot.stop_timeout_s == 5.0 < robot.ack_timeout_s
    robot.stop_timeout_s = 0.5
    assert robot.stop_timeout_s == 0.5


@pytest.mark.parametrize("bad", [0, -1, 2**32, 2**40, True, 1.5, "1"])
def test_id_start_must_be_a_valid_non_reserved_id(bad):
    with pytest.raises(ValueError, match="^id_start"):
        RobotClient(id_start=bad)


@pytest.mark.parametrize("bad", [-1, 65536, True, "1234", 1234.0])
def test_port_must_be_a_port_number(bad):
    with pytest.raises(ValueError, match="^port"):
        RobotClient("127.0.0.1", bad)


# ------------------------------------------------------------------------------------------ per-call timeouts
@pytest.mark.timeout(10)
@pytest.mark.parametrize("bad", [math.nan, math.inf, -1.0, 0.0, True, "5"])
async def test_bad_timeout_s_of_every_method_is_a_value_error_and_nothing_is_sent(bad):
    server = ScriptedServer({"break": Reply(silent=True)})
    try:
        async with RobotClient(connector=server.connector()) as robot:
            calls = [
                lambda: robot.cmdexec(MoveToolZ(1), timeout_s=bad),
                lambda: robot.cmdexec(SetSpeed(5), MoveToolZ(1), timeout_s=bad),
                lambda: robot.cmdexec_joined(SetSpeed(5), MoveToolZ(1), timeout_s=bad),
                lambda: robot.stop(timeout_s=bad),
                lambda: robot.here(timeout_s=bad),
                lambda: robot.hello(timeout_s=bad),
            ]
            for call in calls:
                with pytest.raises(ValueError, match="^timeout_s"):
                    await call()
            assert robot.pending_ids == () and robot.stats.messages_sent == 0
            sub = robot.submit(Break())
            with pytest.raises(ValueError, match="^timeout_s"):
                await sub.wait(timeout_s=bad)
            with pytest.raises(AckTimeout):  # the submission is still waitable with a good timeout
                await sub.wait(timeout_s=0.01)
    finally:
        await server.close()
    assert [line.split(b":")[1] for line in server.lines()] == [b"break"]


# ------------------------------------------------------------------------------------------ message IDs
@pytest.mark.timeout(10)
async def test_ids_wrap_past_ffffffff_without_ever_issuing_00000000():
    server = ScriptedServer()
    try:
        async with RobotClient(connector=server.connector(), id_start=0xFFFFFFFE) as robot:
            for _ in range(3):
                await robot.cmdexec(Here())
            await robot.cmdexec_joined(SetSpeed(5), MoveToolZ(1))     # a batch after the wrap
        async with RobotClient(connector=server.connector(), id_start=0xFFFFFFFF) as robot:
            await robot.cmdexec_joined(SetSpeed(5), MoveToolZ(1))     # a batch across the wrap
    finally:
        await server.close()
    ids = [i for c in server.connections for i in c.ids("recv")]
    assert ids == ["fffffffe", "ffffffff", "00000001", "00000002", "00000003", "00000004",
                   "ffffffff", "00000001", "00000002"]


@pytest.mark.timeout(10)
async def test_an_id_still_pending_or_given_up_is_never_issued_again():
    """The counter comes round to an ID whose message is still pending (a long break) or was given up (its late
    ack may still arrive): the client skips it, for one message and for a batch."""
    server = ScriptedServer({"break": Reply(silent=True)})
    try:
        async with RobotClient(connector=server.connector(), id_start=0x100) as robot:
            held = robot.submit(Break())                       # 00000100, pending
            with pytest.raises(AckTimeout):
                await robot.cmdexec(Break(), timeout_s=0.01)  # 00000101, given up
            pending, gone = held.ids[0], "00000101"
            assert pending == "00000100" and robot.pending_ids == (pending,)
            robot.registry.come_round(0x100)                  # as after 2**32 - 1 more IDs
            await robot.cmdexec(Here())
            robot.registry.come_round(0x100)
            await robot.cmdexec_joined(SetSpeed(5), Skill("enable_air"))
            held.cancel()
    finally:
        await server.close()
    ids = server.connections[0].ids("recv")
    # 00000102 is issued twice: its first message was acked (no longer pending) before the counter came round
    assert ids == [pending, gone, "00000102", "00000102", "00000103"]


@settings(max_examples=40, deadline=None)
@given(start=st.integers(0xFFFFFFF0, 0xFFFFFFFF) | st.integers(1, 4),
       batches=st.lists(st.integers(1, 7), min_size=1, max_size=8))
def test_property_ids_are_unique_and_never_reserved(start, batches):
    async def run() -> list[str]:
        server = ScriptedServer()
        try:
            async with RobotClient(connector=server.connector(), id_start=start) as robot:
                for n in batches:
                    await robot.cmdexec_joined(*[Here()] * n)
        finally:
            await server.close()
        return server.connections[0].ids("recv")

    ids = asyncio.run(run())
    assert len(ids) == sum(batches)
    assert NO_ID not in ids and len(set(ids)) == len(ids)
    assert all(len(i) == 8 and int(i, 16) > 0 for i in ids)


# ------------------------------------------------------------------------------------------ the send CLI
@pytest.mark.parametrize("argv", [["--timeout", "-1", "here"], ["--timeout", "nan", "here"],
                                  ["--connect-timeout", "0", "here"], ["--port", "70000", "here"]])
def test_send_cli_refuses_bad_values_with_a_message_not_a_traceback(argv, capsys):
    assert send_main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("aioadept send: ") and "Traceback" not in err
