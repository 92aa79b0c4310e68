"""What ``status`` reports as the last error, per backend (docs/protocol.md 4.7): the sim reports the last skill that
failed; the V+ server the last V+ error of its executor task (ERROR(-1, 0)), which its own refusals (-610 from
its INRANGE check) are not. Real TCP; the V+ server runs on the emulator as a child process."""

from __future__ import annotations

from pathlib import Path

import pytest

from aioadept.ports import free_port
from aioadept import MoveTo
from aioadept.client import RobotClient
from aioadept.errors import CommandError
from aioadept.protocol import ErrorCode
from aioadept.testing.nodes import running_node
from aioadept.testing.sim import running_sim

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
FAR = (2000.0, 0.0, 500.0, 0.0, 180.0, 0.0)     # beyond the Viper s850's 855 mm reach


@pytest.mark.timeout(20)
async def test_the_sim_reports_the_last_failed_skill_until_the_next_failure():
    async with running_sim(instant=True) as sim:
        async with RobotClient(sim.host, sim.port) as robot:
            with pytest.raises(CommandError) as refused:
                await robot.cmdexec(MoveTo(FAR))
            st = await robot.status()
            assert st.error_code == ErrorCode.OUT_OF_REACH == refused.value.code
            assert st.error_text and ":" not in st.error_text
            assert not st.moving and st.power and not st.estop
            await robot.cmdexec(MoveTo((400.0, 0.0, 500.0, 0.0, 180.0, 0.0)))   # a success does not clear it
            assert (await robot.status()).error_code == ErrorCode.OUT_OF_REACH


@pytest.mark.timeout(60)
async def test_the_v_plus_server_reports_the_last_v_plus_error_of_its_executor(tmp_path):
    cfg = (VPLUS / "rsconfig.V2").read_text()
    assert "rs.chkrange = TRUE" in cfg
    (tmp_path / "rsconfig.V2").write_text(cfg.replace("rs.chkrange = TRUE", "rs.chkrange = FALSE"))
    files = [str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(tmp_path / "rsconfig.V2")]
    port = free_port()
    async with running_node("sim", "--vplus", *files, "--run", "rs.main", "--map-port", f"1234={port}",
                            "--state-endpoint", "none", log_path=tmp_path / "sim.log", ready_timeout_s=45):
        async with RobotClient("127.0.0.1", port) as robot:
            assert (await robot.status()).error_code == 0
            # without the INRANGE check V+ itself refuses the move: a V+ error, trapped (REACTE) into -300
            with pytest.raises(CommandError) as refused:
                await robot.cmdexec(MoveTo(FAR))
            assert refused.value.code == ErrorCode.SKILL_FAILED
            st = await robot.status()
            assert st.error_code < 0 and st.error_code != ErrorCode.SKILL_FAILED
            assert str(st.error_code) in str(refused.value), "the V+ code the error ack named"
            assert st.error_text, "with its V+ text"
            assert not st.moving and st.power and not st.estop
