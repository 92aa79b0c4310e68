"""When the emulated V+ server dies after READY (``aioadept sim --vplus ... --run rs.main``), nothing is left
half alive: the arm is braked, every client's connection ends and its pending commands fail with ConnectionLost
(which IDs are known done, which unknown), and the process exits 1 with one stderr line saying which task and
program died, where and why (docs/vplus.md, "When the program dies").

One test per way of dying, each through a real child process, real TCP and the real ZeroMQ state stream:

- a V+ runtime error halts the executor (a user skill whose own REACTE trap fails);
- the executor's task ends without an error (a user skill that HALTs) while the reader runs on;
- the executor's task PAUSEs (nothing in the sim can PROCEED it);
- a Python exception inside a task (the reader's READ; an emulator bug there becomes the task's error);
- a Python exception in the scheduler, outside any task;
- a Python exception in an I/O callback of the emulator's TCP device (asyncio's exception handler).

The last three need an emulator bug: the child runs ``aioadept sim`` with one emulator function patched to raise
when it sees the test's trigger (a small script in tmp_path), so nothing of the kind is shipped.
"""

from __future__ import annotations

import asyncio
import contextlib
import sys
from pathlib import Path

import pytest

from aioadept import Skill
from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import Subscriber
from aioadept.client import RobotClient
from aioadept.commands import Break, MoveJoints, SetSpeed
from aioadept.errors import ConnectionLost

from deathwatch import record

VPLUS = Path(__file__).resolve().parents[2] / "vplus"

USER_SKILLS = '''	CALL rs.addskill("halt_now", 0)
	CALL rs.addskill("crash", 0)
	CALL rs.addskill("boom", 0)
	CALL rs.addskill("rdboom", 0)
	CALL rs.addskill("cbboom", 0)
	CALL rs.addskill("shutdown", 0)
	CALL rs.addskill("pause_now", 0)
.END

.PROGRAM halt_now()
; a user skill that halts the program: the executor's task ends, the reader's runs on
	HALT
.END

.PROGRAM crash()
; a user skill whose own error trap fails: the error halts the executor's task
	REACTE crash.trap
	x = 1/0
.END

.PROGRAM crash.trap()
	y = 1/0
.END

.PROGRAM boom()
; sets the global that the patched scheduler (PATCH) raises on
	emu.boom = 1
.END

.PROGRAM rdboom()
; never runs: the patched READ (PATCH) raises when it reads this skill's line
.END

.PROGRAM pause_now()
; a user skill that PAUSEs (for a debugger at the controller's terminal): nothing in the sim can PROCEED it
	PAUSE
.END

.PROGRAM shutdown()
; the clean way out: both of the server's loops end (rs.halt)
	CALL rs.halt()
.END

.PROGRAM cbboom()
; never runs: the patched TCP receive callback (PATCH) raises when this skill's line arrives
.END
'''

PATCH = '''import sys
from aioadept.vplus import iodev, runtime

run_round = runtime.Runtime.run_round


def patched_round(self):
    n = run_round(self)
    if "emu.boom" in self.globals:
        raise RuntimeError("injected scheduler fault")
    return n


pop = iodev.TcpLun.pop


def patched_pop(self):
    got = pop(self)
    if got is not None and any("rdboom" in str(x) for x in got):
        raise RuntimeError("injected reader fault")
    return got


received = iodev._Proto.data_received


def patched_received(self, data):
    if b"cbboom" in data:
        raise RuntimeError("injected callback fault")
    received(self, data)


runtime.Runtime.run_round = patched_round
iodev.TcpLun.pop = patched_pop
iodev._Proto.data_received = patched_received
from aioadept.cli import main

sys.exit(main())
'''

TARGET_J1_DEG = 60.0


def server_files(tmp_path: Path) -> list[str]:
    cfg = (VPLUS / "rsconfig.V2").read_text()
    end = cfg.rindex(".END")          # rs.config's: the user skills are registered at its end
    (tmp_path / "rsconfig.V2").write_text(cfg[:end] + USER_SKILLS)
    return [str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(tmp_path / "rsconfig.V2")]


class Sim:
    def __init__(self, proc: asyncio.subprocess.Process, port: int, state: str) -> None:
        self.proc, self.port, self.state = proc, port, state
        self.out: list[str] = []


@contextlib.asynccontextmanager
async def vplus_sim(tmp_path: Path):
    script = tmp_path / "patched_sim.py"
    script.write_text(PATCH)
    argv = [sys.executable, str(script), "sim", "--vplus", *server_files(tmp_path), "--run", "rs.main",
            "--map-port", "1234=0", "--map-port", "1235=0", "--state-endpoint", "tcp://127.0.0.1:0",
            "--state-rate-hz", "100"]
    proc = await asyncio.create_subprocess_exec(*argv, stdout=asyncio.subprocess.PIPE,
                                                stderr=asyncio.subprocess.PIPE, start_new_session=True)
    try:
        assert proc.stdout is not None
        async with asyncio.timeout(30):
            while True:
                line = (await proc.stdout.readline()).decode()
                assert line, f"the sim exited before READY: {(await proc.stderr.read()).decode()}"
                if line.startswith("READY") and "vport=1234" in line:
                    fields = dict(f.split("=", 1) for f in line.split()[1:])
                    break
        sim = Sim(proc, int(fields["port"]), fields["state"])

        async def drain() -> None:
            while raw := await proc.stdout.readline():
                sim.out.append(raw.decode().rstrip())

        drainer = asyncio.ensure_future(drain())
        yield sim
        drainer.cancel()
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()


# (trigger skill, the trigger's own ack may have come (it ran before the fault), what the stderr line says)
WAYS = [
    pytest.param("crash", False, ["V+ task 0 (rs.main) stopped:", "*Division by 0*", "rsconfig.V2:",
                                  "in crash.trap"], id="vplus-error-halts-the-executor"),
    pytest.param("halt_now", False, ["V+ task 0 (rs.main) halted by HALT at", "rsconfig.V2:", "in halt_now",
                                     "task 2 (rs.reader)"], id="executor-task-ends"),
    pytest.param("pause_now", False, ["V+ task 0 (rs.main) paused by PAUSE at", "rsconfig.V2:", "in pause_now",
                                      "nothing can PROCEED it"], id="executor-task-pauses"),
    pytest.param("rdboom", False, ["V+ task 2 (rs.reader) halted by HALT at", "in rs.rdtrap (its error trap, called for", "*Emulator internal error*",
                                   "RuntimeError: injected reader fault", "rserver.V2:", "in rs."],
                 id="python-exception-in-the-reader-task"),
    pytest.param("boom", True, ["emulator internal error RuntimeError: injected scheduler fault",
                                "patched_sim.py:"], id="python-exception-in-the-scheduler"),
    pytest.param("cbboom", False, ["emulator internal error RuntimeError: injected callback fault",
                                   "patched_sim.py:", "data_received"], id="python-exception-in-an-io-callback"),
]


@pytest.mark.timeout(90)
@pytest.mark.parametrize(("trigger", "trigger_may_ack", "says"), WAYS)
async def test_when_the_server_dies_the_arm_stops_clients_learn_and_the_process_exits_1(
        tmp_path, trigger, trigger_may_ack, says):
    async with vplus_sim(tmp_path) as sim:
        states: list[RobotState] = []
        async with Subscriber(sim.state, topics=[ROBOT_STATE_TOPIC]) as sub:
            recorder = asyncio.ensure_future(record(sub, states, sim.proc))
            async with RobotClient("127.0.0.1", sim.port) as robot:
                # a slow joint move the server acks at once (forward processing): the arm is moving
                await robot.cmdexec(SetSpeed(5), MoveJoints([TARGET_J1_DEG, -90, 180, 0, 90, 0],
                                                            break_move=False))
                await asyncio.sleep(0.3)
                pending = robot.submit(Skill(trigger), Break())
                t0 = asyncio.get_running_loop().time()
                with pytest.raises(ConnectionLost) as lost:
                    await pending.wait(timeout_s=10)
                t_lost = asyncio.get_running_loop().time() - t0
            rc = await asyncio.wait_for(sim.proc.wait(), 15)
            await asyncio.wait_for(recorder, 10)
        err = (await sim.proc.stderr.read()).decode()

    # the client: its pending commands failed promptly, each either known done or unresolved
    assert t_lost < 3.0, t_lost
    trig_id, break_id = pending.ids
    assert break_id in lost.value.unresolved          # the break waits for a motion that never completes
    assert set(lost.value.acked) | set(lost.value.unresolved) == {trig_id, break_id}
    if not trigger_may_ack:
        assert trig_id in lost.value.unresolved

    # the process: exit 1, one line on stderr naming who died, where and why
    assert rc == 1, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("aioadept sim: ")
    for part in says:
        assert part in lines[0], (part, lines[0])

    # the arm: it moved, then stopped short of the target, and the stream shows it at rest before it ended
    assert states, "no state sample arrived"
    assert max(s.joints_deg[0] for s in states) > 0.5, "the arm never moved"
    last = states[-1]
    assert not last.in_motion
    assert last.joints_deg[0] < TARGET_J1_DEG - 20, last.joints_deg     # braked, not run to its target
    assert states[-2].joints_deg == last.joints_deg


@pytest.mark.timeout(60)
async def test_a_clean_rs_halt_is_no_death_the_last_acks_go_out_and_the_exit_status_is_0(tmp_path):
    async with vplus_sim(tmp_path) as sim:
        async with RobotClient("127.0.0.1", sim.port) as robot:
            await robot.cmdexec(Skill("shutdown"))              # acked: the reader flushes before it ends
            rc = await asyncio.wait_for(sim.proc.wait(), 15)
        err = (await sim.proc.stderr.read()).decode()
    assert rc == 0, err
    assert [ln for ln in err.splitlines() if ln.strip()] == ["aioadept sim: every V+ task has ended"]


@pytest.mark.timeout(90)
async def test_an_error_in_the_reader_brakes_the_arm_and_no_command_queued_behind_the_motion_runs(tmp_path):
    # On a controller nobody else brakes the arm when the reader (the task that reads every stop) dies: its own
    # error trap, rs.rdtrap, must brake it and keep task 1 from running on through the queue. Here the supervisor
    # would brake everything GRACE_S (0.5 s) after the reader halts; a queued motion started meanwhile would show
    # in the state stream as the arm turning back.
    async with vplus_sim(tmp_path) as sim:
        states: list[RobotState] = []
        async with Subscriber(sim.state, topics=[ROBOT_STATE_TOPIC]) as sub:
            recorder = asyncio.ensure_future(record(sub, states, sim.proc))
            async with RobotClient("127.0.0.1", sim.port) as robot:
                await robot.cmdexec(SetSpeed(5))
                # task 1 waits in the first move (it breaks: its ack comes at the end); the second waits in the queue
                moves = robot.submit(MoveJoints([TARGET_J1_DEG, -90, 180, 0, 90, 0]),
                                     MoveJoints([-TARGET_J1_DEG, -90, 180, 0, 90, 0]))
                await asyncio.sleep(0.5)
                fault = robot.submit(Skill("rdboom"))
                for pending in (fault, moves):  # neither move is acked: the first was braked, the second never ran
                    with pytest.raises(ConnectionLost):
                        await pending.wait(timeout_s=10)
            rc = await asyncio.wait_for(sim.proc.wait(), 15)
            await asyncio.wait_for(recorder, 10)
        err = (await sim.proc.stderr.read()).decode()
    assert rc == 1, err
    assert "in rs.rdtrap (its error trap, called for" in err, err
    assert any(line.startswith("[2] [rs] reader failed: V+ ") for line in sim.out), sim.out
    j1 = [s.joints_deg[0] for s in states]
    peak = max(j1)
    assert 0.5 < peak < TARGET_J1_DEG - 20, j1          # it moved, and was braked well short of the first target
    after = j1[j1.index(peak):]
    assert min(after) > peak - 0.01, after             # and never turned back toward the second (which, SPEED
    #                                                    applying to one motion only, would run at full speed)
    assert not states[-1].in_motion
