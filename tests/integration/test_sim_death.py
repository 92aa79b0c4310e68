"""When the Python sim's server dies after READY (``aioadept sim``, no ``--vplus``), nothing is left half alive: the
arm is braked, every client's connection ends and its pending commands fail with ConnectionLost (which IDs are known
done, which unknown), the state stream shows the arm at rest before it ends, and the process exits 1 with one
stderr line naming the task that died and the exception, with the file:line it was raised at (docs/sim.md, "When
the server dies").

One test per way of dying, each through a real child process, real TCP and the real ZeroMQ state stream; the bug is
injected with the test-only ``--fault raise=POINT`` (aioadept.sim.server.RAISE_POINTS), which raises the first
time that point is passed while the arm moves:

- the executor (the timer that runs the controller's queue) while a motion runs;
- a connection's reader, on a line it has read;
- the world's update (the feeder's step), run by the executor (in wait_sig) or by the state stream's sample;
- a loop callback, outside any guard: the exception reaches asyncio's exception handler.

And one way that is no death: the state stream failing to send (as a full or broken socket would) drops samples,
logs once, and the server serves on.
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
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

TARGET_J1_DEG = 60.0

WORLD = """
[world]
table_z_mm = 380.0
[[world.parts]]
id = 5
shape = "cylinder"
size_mm = [30, 40]
x_mm = 480.0
y_mm = 0.0
[world.feeder]
x_mm = 480.0
y_mm = 0.0
sensor = 1002
queue = 3
interval_s = 0.5
"""


class Sim:
    def __init__(self, proc: asyncio.subprocess.Process, port: int, state: str) -> None:
        self.proc, self.port, self.state = proc, port, state


@contextlib.asynccontextmanager
async def sim_process(*args: str):
    argv = [sys.executable, "-m", "aioadept", "sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0",
            "--state-rate-hz", "100", *args]
    proc = await asyncio.create_subprocess_exec(*argv, stdout=asyncio.subprocess.PIPE,
                                                stderr=asyncio.subprocess.PIPE, start_new_session=True)
    try:
        assert proc.stdout is not None
        async with asyncio.timeout(30):
            line = (await proc.stdout.readline()).decode()
        assert line.startswith("READY"), f"no READY: {line!r} {(await proc.stderr.read()).decode()}"
        fields = dict(f.split("=", 1) for f in line.split()[1:])
        yield Sim(proc, int(fields["port"]), fields["state"])
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()


# wait_sig polls its input every 16 ms (the executor's timer runs, the I/O advances) while the arm moves; a second
# move waits for its motion slot, holding the executor without touching the I/O (only the state samples do).
WAIT_SIG = "wait_sig"
NEXT_MOVE = "move"

# (fault point, extra options, the commands pending at the death, what the stderr line names: the task that died)
WAYS = [
    pytest.param("executor", [], WAIT_SIG, "the executor died of", id="executor-while-a-motion-runs"),
    pytest.param("reader", [], WAIT_SIG, "the reader of client 127.0.0.1:", id="a-connections-reader"),
    pytest.param("world", ["--world", "WORLD"], WAIT_SIG,
                 "the world's update (run by the executor, handling a line from client 127.0.0.1:",
                 id="the-worlds-update-in-a-skill"),
    pytest.param("world", ["--world", "WORLD"], NEXT_MOVE, "the world's update (run by the state publisher) died of",
                 id="the-worlds-update-in-a-state-sample"),
    pytest.param("callback", [], WAIT_SIG, "an event loop callback (SimServer._on_timer(", id="loop-exception-handler"),
]


@pytest.mark.timeout(60)
@pytest.mark.parametrize(("point", "options", "pending_kind", "says"), WAYS)
async def test_when_the_server_dies_the_arm_stops_clients_learn_and_the_process_exits_1(
        tmp_path: Path, point: str, options: list[str], pending_kind: str, says: str) -> None:
    if "WORLD" in options:
        (tmp_path / "cell.toml").write_text(WORLD)
        options = [str(tmp_path / "cell.toml") if o == "WORLD" else o for o in options]
    async with sim_process("--fault", f"raise={point}", *options) as sim:
        states: list[RobotState] = []
        async with Subscriber(sim.state, topics=[ROBOT_STATE_TOPIC]) as sub:
            recorder = asyncio.ensure_future(record(sub, states, sim.proc))
            async with RobotClient("127.0.0.1", sim.port) as robot, RobotClient("127.0.0.1", sim.port) as idle:
                await idle.here()                                  # a second client, connected and idle
                # A joint move of several seconds, acked at once (forward processing): the arm is moving.
                await robot.cmdexec(SetSpeed(5), MoveJoints([TARGET_J1_DEG, -90, 180, 0, 90, 0],
                                                            break_move=False))
                await asyncio.sleep(0.3)
                first = (Skill("wait_sig", 1001, 5) if pending_kind == WAIT_SIG
                         else MoveJoints([0, -90, 180, 0, 90, 0], break_move=False))
                pending = robot.submit(first, Break())
                t0 = asyncio.get_running_loop().time()
                with pytest.raises(ConnectionLost) as lost:
                    await pending.wait(timeout_s=10)
                t_lost = asyncio.get_running_loop().time() - t0
                # the idle client's connection has ended too: nothing more is sent to a dead server
                with pytest.raises(ConnectionLost, match=f"connection to 127.0.0.1:{sim.port} (is )?lost"):
                    await idle.here()
            rc = await asyncio.wait_for(sim.proc.wait(), 15)
            await asyncio.wait_for(recorder, 10)
        err = (await sim.proc.stderr.read()).decode()

    # the client: its pending commands failed promptly, each known done or unresolved
    assert t_lost < 3.0, t_lost
    first_id, break_id = pending.ids
    assert set(lost.value.unresolved) == {first_id, break_id}, lost.value   # neither could have completed
    assert lost.value.acked == ()

    # the process: exit 1, one line on stderr naming the task, the exception and where it was raised
    assert rc == 1, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith("aioadept sim: "), line
    assert f"InjectedFault: injected {point} fault at server.py:" in line, line
    assert line.endswith("the arm was braked and every connection closed"), line
    assert says in line, line

    # the arm: it moved, then stopped well short of its target, and the stream shows it at rest before it ended
    assert states, "no state sample arrived"
    assert max(s.joints_deg[0] for s in states) > 0.5, "the arm never moved"
    last = states[-1]
    assert not last.in_motion, last
    assert last.joints_deg[0] < TARGET_J1_DEG - 20, last.joints_deg     # braked, not run to its target
    assert states[-2].joints_deg == last.joints_deg


@pytest.mark.timeout(60)
async def test_a_state_stream_that_cannot_send_is_no_death_samples_are_dropped_and_logged_once() -> None:
    async with sim_process("--fault", "raise=state-send") as sim:
        states: list[RobotState] = []
        async with Subscriber(sim.state, topics=[ROBOT_STATE_TOPIC]) as sub:
            recorder = asyncio.ensure_future(record(sub, states, sim.proc))
            async with RobotClient("127.0.0.1", sim.port) as robot:
                here0 = await robot.here()
                # about a second of motion, during which every sample fails to send
                await robot.cmdexec(SetSpeed(20), MoveJoints([10, -90, 180, 0, 90, 0], break_move=False))
                mid = await robot.here()                       # the server serves on meanwhile
                await robot.cmdexec(Break())                   # and its motion completes
                end = await robot.here()
                async with asyncio.timeout(5):                 # samples flow again once the arm is at rest
                    while not (states and states[-1].joints_deg[0] > 9.99):
                        await asyncio.sleep(0.02)
                await asyncio.sleep(0.1)
            sim.proc.send_signal(signal.SIGTERM)
            rc = await asyncio.wait_for(sim.proc.wait(), 15)
            await asyncio.wait_for(recorder, 10)
        err = (await sim.proc.stderr.read()).decode()

    assert rc == 0, err
    assert abs(here0.y) < 1e-6 and end.y > 80, (here0, mid, end)    # J1 turned 10 deg
    # the stream had a gap while the arm moved: no sample between the start and the end of the motion
    assert not any(s.in_motion for s in states), [s for s in states if s.in_motion][:1]
    assert states[-1].joints_deg[0] == pytest.approx(10.0, abs=1e-6)
    # two lines, not a traceback per sample: when it began (and why), and when it ended (and how much was lost)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 2, err
    assert "state stream: a sample was not sent (BusError: injected state-send fault)" in lines[0], lines
    assert "state stream: sending again after" in lines[1] and "dropped samples" in lines[1], lines


@pytest.mark.timeout(60)
@pytest.mark.parametrize(("argv", "says"), [
    (["--fault", "raise=execute"], "raise=execute: not a fault point (executor, reader, world, callback, state-send)"),
    (["--fault", "raise=world"], "fault raise=world needs a world (--world)"),
    (["--vplus", "x.V2", "--run", "x", "--fault", "raise=reader"], "--fault raise=POINT tests the Python sim's"),
])
async def test_a_fault_that_cannot_act_is_one_line_and_exit_2(argv: list[str], says: str) -> None:
    proc = await asyncio.create_subprocess_exec(sys.executable, "-m", "aioadept", "sim", "--port", "0", *argv,
                                                stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    out, err = await asyncio.wait_for(proc.communicate(), 30)
    lines = [ln for ln in err.decode().splitlines() if ln.strip()]
    assert proc.returncode == 2, err
    assert len(lines) == 1 and says in lines[0], err
    assert out == b""


@pytest.mark.timeout(30)
async def test_in_process_the_server_dies_the_same_way_and_says_so() -> None:
    # running_sim (aioadept.testing): no CLI, no exit status; the server brakes, closes, and sets dead/death.
    from aioadept.sim.server import Faults, InjectedFault
    from aioadept.testing.sim import running_sim

    async with running_sim(faults=Faults(raise_at="executor"), state_endpoint=None) as sim:
        async with RobotClient(sim.host, sim.port) as robot:
            await robot.cmdexec(SetSpeed(5), MoveJoints([TARGET_J1_DEG, -90, 180, 0, 90, 0], break_move=False))
            await asyncio.sleep(0.3)
            with pytest.raises(ConnectionLost):
                await robot.submit(Skill("wait_sig", 1001, 5), Break()).wait(timeout_s=10)
        await asyncio.wait_for(sim.dead.wait(), 5)
        task, exc = sim.death
        assert task == "the executor" and isinstance(exc, InjectedFault), sim.death
        t_rest = sim.controller.trajectory.t_rest_s
        assert t_rest < sim.now() + 1.0                                   # braked: at rest within a second
        assert sim.controller.joints_at(t_rest)[0] < TARGET_J1_DEG - 20   # short of the target
        async with asyncio.timeout(5):                                    # and it serves nobody any more
            with pytest.raises(OSError):
                _, w = await asyncio.open_connection(sim.host, sim.port)
                w.close()
