"""Both backends agree on limits, to the last digit of the text (docs/protocol.md 3.2).

A number past a limit by less than a V+ REAL's precision (single: VAL("512.00001") is 512 exactly) is refused
like any number past the limit (-410, or -1003 for a joint), as the sim (which reads doubles) always did; one just inside is accepted by both.
(The V+ server once took ``signal:512.00001`` as output 512, ``wait_sig:1002,3600.0001`` as an hour's wait and
``set_speed:100.000001`` as 100 %.)
"""

from __future__ import annotations

import pytest

from aioadept.protocol import ErrorCode, Status

ILLEGAL, JOINT = ErrorCode.ILLEGAL_VALUE, ErrorCode.JOINT_LIMIT
PAST = [("signal:512.00001", ILLEGAL), ("signal:-512.000001", ILLEGAL), ("wait_sig:1002,3600.0001", ILLEGAL),
        ("set_speed:100.000001", ILLEGAL)]


def past_last_joint(arm) -> str:
    """``move_joints`` to home but the last joint 0.00001 past its upper limit (the text keeps every digit)."""
    q = [f"{v:g}" for v in arm.six(arm.home)]
    q[arm.last] = f"{arm.m.limits.max_deg[arm.last]:g}.00001"
    return "move_joints:" + ",".join(q)
INSIDE = ["wait_sig:-2001,3599.99999999", "set_speed:100.0000", "signal:-8.0000"]


@pytest.mark.timeout(60)
async def test_a_number_past_a_limit_by_less_than_a_real_is_refused_and_one_inside_is_taken(server, arm):
    a = await server.connect()
    for i, (cmd, code) in enumerate([*PAST, (past_last_joint(arm), JOINT)]):
        mid = f"kl{i:06d}"
        await a.send(f"{mid}:{cmd}")
        ack = await a.ack()
        assert (ack.id, ack.status, ack.error_code) == (mid, Status.ERROR, code), (cmd, ack)
    for i, cmd in enumerate(INSIDE):
        mid = f"km{i:06d}"
        await a.send(f"{mid}:{cmd}")
        ack = await a.ack()
        assert (ack.id, ack.status) == (mid, Status.DONE), (cmd, ack)
    await a.send("kn000001:sig:512")
    ack = await a.ack()
    assert ack.status is Status.DONE and ack.extra == ("0",), ack  # output 512 never switched
    await a.close()
