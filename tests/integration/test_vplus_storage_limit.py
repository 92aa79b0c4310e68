"""A user V+ skill that allocates without end (``aioadept sim --vplus``): it gets V+'s own memory error,
``*Not enough storage area*``, once the emulator's program memory (runtime.STORAGE_LIMIT array elements) is full,
instead of growing the process without bound; a stop sent meanwhile is acked once the skill has ended, and the
server serves on. Real child process, real TCP (docs/vplus.md, "Program memory")."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from aioadept import Skill
from aioadept.client import RobotClient
from aioadept.errors import CommandAborted, CommandError
from aioadept.testing.nodes import running_node
from aioadept.ports import free_port

VPLUS = Path(__file__).resolve().parents[2] / "vplus"

USER_SKILLS = '''	CALL rs.addskill("grow", 0)
	CALL rs.addskill("grows", 0)
	CALL rs.addskill("growl", 0)
	CALL rs.addskill("growa", 0)
.END

.PROGRAM grow()
; a global array of numbers, one element more each iteration, no WAIT
	i = 0
	WHILE TRUE DO
	    big[i] = i
	    i = i+1
	END
.END

.PROGRAM grows()
; a global array of 100-character strings
	$t = "0123456789"
	$t = $t+$t+$t+$t+$t+$t+$t+$t+$t+$t
	i = 0
	WHILE TRUE DO
	    $bigs[i] = $t
	    i = i+1
	END
.END

.PROGRAM growl()
; a LOCAL array, two dimensions
	LOCAL m[]
	i = 0
	WHILE TRUE DO
	    m[i,1] = i
	    i = i+1
	END
.END

.PROGRAM growa()
; an AUTO array of a called program
	CALL growa.in()
.END

.PROGRAM growa.in()
	AUTO n[16]
	i = 0
	WHILE TRUE DO
	    n[i] = i
	    i = i+1
	END
.END
'''

NO_STORAGE = -611                     # aioadept.vplus.errors.NO_STORAGE


def server_files(tmp_path: Path) -> list[str]:
    cfg = (VPLUS / "rsconfig.V2").read_text()
    end = cfg.rindex(".END")          # rs.config's: the user skills are registered at its end
    # the executor's restart after a stop (rs.unstick, rs.stwd) would free a skill's arrays before the memory error
    # comes on a loaded machine; this test is about the memory limit, so the restart waits longer than it
    (tmp_path / "rsconfig.V2").write_text(cfg[:end] + "\trs.stwd = 30\n" + USER_SKILLS)
    return [str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(tmp_path / "rsconfig.V2")]


def rss_mb(pid: int) -> float:
    status = Path(f"/proc/{pid}/status").read_text()
    return int(status.split("VmRSS:")[1].split()[0]) / 1024


@pytest.mark.timeout(60)
@pytest.mark.parametrize("skill", ["grow", "grows", "growl", "growa"])
async def test_a_skill_that_allocates_without_end_gets_the_v_plus_memory_error_and_a_stop_is_acked(tmp_path, skill):
    port = free_port()
    async with running_node("sim", "--vplus", *server_files(tmp_path), "--run", "rs.main",
                            "--map-port", f"1234={port}", "--map-port", "1235=0", "--state-endpoint", "none",
                            log_path=tmp_path / "sim.log", ready_timeout_s=60) as sim:
        pid = sim.proc.pid
        rss0 = rss_mb(pid)
        async with RobotClient("127.0.0.1", port) as robot:
            pending = robot.submit(Skill(skill))
            await asyncio.sleep(0.1)                       # it is allocating now
            loop = asyncio.get_running_loop()
            t0 = loop.time()
            await robot.stop(timeout_s=10)
            t_stop = loop.time() - t0
            # the skill ended with the V+ error (or, the stop having come first, aborted): not by the stop
            with pytest.raises((CommandError, CommandAborted)) as failed:
                await pending.wait(timeout_s=5)
            grown = rss_mb(pid) - rss0
            await robot.here()                             # the server serves on
            # memory stays full until the arrays are freed: the next allocation fails at once, with V+'s error
            with pytest.raises(CommandError) as again:
                await robot.cmdexec(Skill(skill), timeout_s=5)
    assert t_stop < 5.0, t_stop
    assert grown < 150, f"the process grew by {grown:.0f} MB"
    # the shipped server acks a skill's V+ error as -300 with the V+ code and text (rs.onerr)
    assert f"V+ {NO_STORAGE} *Not enough storage area*" in again.value.message, again.value
    if isinstance(failed.value, CommandError):
        assert f"V+ {NO_STORAGE} *Not enough storage area*" in failed.value.message, failed.value
    print(f"{skill}: stop acked after {t_stop:.3f} s, the process grew by {grown:.0f} MB")
