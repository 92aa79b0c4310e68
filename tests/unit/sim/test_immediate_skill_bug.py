"""A user skill's bug is its own error ack (-300 SKILL_FAILED) and never the server's, whether the skill runs in the
executor's turn or at once (``immediate`` / ``readonly``): since a controller exception is now the sim server's
death (docs/sim.md, "When the server dies"), the immediate path must answer it as the queued path always did."""

import pytest

from aioadept.protocol import ErrorCode, Status, parse_command
from aioadept.sim.controller import Controller


def boom(ctl, args):
    raise ZeroDivisionError("user skill divided by zero")


@pytest.mark.parametrize("how", [{"immediate": True}, {"readonly": True}, {}])
def test_a_failing_user_skill_is_answered_skill_failed_and_the_next_command_runs(how):
    ctl = Controller(instant=True)
    ctl.connect("a")
    ctl.register("boom", boom, **how)
    out = ctl.handle(parse_command(b"00000001:boom"), "a", 0.0)
    (ack,) = [o.ack for o in out]
    assert ack.id == "00000001" and ack.status is Status.ERROR
    assert ack.error_code == ErrorCode.SKILL_FAILED
    assert ack.error_message == "ZeroDivisionError; user skill divided by zero"   # no colon on the wire
    out = ctl.handle(parse_command(b"00000002:here"), "a", 0.001)
    assert [(o.ack.id, o.ack.status) for o in out] == [("00000002", Status.DONE)]
