"""The shipped V+ server (vplus/*.V2) served by ``aioadept sim --vplus`` in a child process, over real TCP."""

from __future__ import annotations

from pathlib import Path

import pytest

from aioadept import MoveToolZ, SetSpeed, Skill
from aioadept.client import RobotClient
from aioadept.errors import CommandError
from aioadept.testing.nodes import running_node

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
FILES = [str(VPLUS / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]


def sim_args(*extra: str) -> tuple[str, ...]:
    return ("--vplus", *FILES, "--run", "rs.main", "--map-port", "1234=0", "--map-port", "1235=0",
            "--state-endpoint", "none", *extra)


@pytest.mark.timeout(60)
async def test_shipped_server_answers_hello_here_and_moves(tmp_path):
    async with running_node("sim", *sim_args("--time-scale", "20"), log_path=tmp_path / "sim.log") as node:
        assert node.ready["vport"] == "1234"
        port = int(node.ready["port"])
        async with RobotClient("127.0.0.1", port) as robot:
            assert await robot.hello() == (1, "aioadept-vplus 0.1.0")
            start = await robot.here()
            res = await robot.cmdexec(SetSpeed(50), MoveToolZ(20.0))        # move_rel_tool + break
            end = await robot.here()
            assert res.messages[-1].ack.t_done_s > res.messages[-2].ack.t_done_s   # break acks at rest
            # tool Z points down at home: 20 mm along it lowers the tool
            assert end.z == pytest.approx(start.z - 20.0, abs=0.01)
            assert (end.x, end.y) == pytest.approx((start.x, start.y), abs=0.01)
            with pytest.raises(CommandError) as info:
                await robot.cmdexec(Skill("set_speed", 500))
            assert info.value.code == -410
            with pytest.raises(CommandError) as info:
                await robot.cmdexec(Skill("move_to", 1000, 0, 0, 0, 180, 0))
            assert info.value.code == -610
            assert await robot.here() == end                                 # a refusal does not move
    log = (tmp_path / "sim.log").read_text()
    assert "[0] [rs] executor running" in log and "[2] READY port=1234" in log
