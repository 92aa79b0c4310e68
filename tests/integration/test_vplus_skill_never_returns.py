"""A user V+ skill that never returns (a loop without WAIT) does not keep a stop's ack: the reader brakes the arm
at once, and when the skill is still running rs.stwd (0.5 s) later it ends the executor's task and starts rs.exec
again, which acks the skill aborted and the stop done; the server then serves and moves as before. Real child
process, real TCP (docs/vplus.md, "stop")."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from aioadept import Skill
from aioadept.client import RobotClient
from aioadept.commands import Break, MoveRelJoints
from aioadept.errors import CommandAborted
from aioadept.testing.nodes import running_node
from aioadept.ports import free_port

VPLUS = Path(__file__).resolve().parents[2] / "vplus"

USER_SKILLS = '''	CALL rs.addskill("spin", 0)
.END

.PROGRAM spin()
	x = 0
	WHILE TRUE DO
	    x = x+1
	END
.END
'''


@pytest.mark.timeout(60)
async def test_a_stop_is_acked_when_a_user_skill_never_returns(tmp_path):
    cfg = (VPLUS / "rsconfig.V2").read_text()
    end = cfg.rindex(".END")
    (tmp_path / "rsconfig.V2").write_text(cfg[:end] + USER_SKILLS)
    files = [str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(tmp_path / "rsconfig.V2")]
    port = free_port()
    async with running_node("sim", "--vplus", *files, "--run", "rs.main", "--map-port", f"1234={port}",
                            "--map-port", "1235=0", "--state-endpoint", "none",
                            log_path=tmp_path / "sim.log", ready_timeout_s=60) as sim:
        async with RobotClient("127.0.0.1", port) as robot:
            pending = robot.submit(Skill("spin"))
            await asyncio.sleep(0.3)                      # spinning in task 1
            await robot.stop(timeout_s=5)                # acked, although the skill never returns
            with pytest.raises(CommandAborted):
                await pending.wait(timeout_s=5)
            # the executor serves again: a motion runs and completes
            before = await robot.here()
            await robot.cmdexec(MoveRelJoints([2, 0, 0, 0, 0, 0]), Break(), timeout_s=10)
            after = await robot.here()
        assert sim.proc.returncode is None
    assert (before.x, before.y) != (after.x, after.y)
