"""Digital I/O and the hand through the real pieces: ``aioadept send`` as a process against the sim over TCP, the
client's commands, the inputs' test API, and the state stream over ZeroMQ."""

from __future__ import annotations

import asyncio
import sys

import pytest

from aioadept import CloseHand, OpenHand, Sig, Signal, WaitSig
from aioadept.client import RobotClient
from aioadept.errors import CommandError
from aioadept.protocol import ErrorCode
from aioadept.testing.sim import running_sim


async def run_send(port: int, *skills: str) -> tuple[int, str, str]:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "aioadept.cli", "send", "--port", str(port), *skills,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    out, err = await proc.communicate()
    return proc.returncode, out.decode(), err.decode()


@pytest.mark.timeout(30)
async def test_aioadept_send_drives_each_io_skill():
    async with running_sim(time_scale=10) as sim:
        code, out, err = await run_send(sim.port, "signal:8,2001", "sig:1001", "sig:8,-8,2001", "close_hand",
                                         "wait_sig:1001,2", "open_hand", "relax_hand")
        assert code == 0, err
        lines = out.splitlines()
        assert [ln.split()[1:3] for ln in lines] == [
            ["signal", "done"], ["sig", "done"], ["sig", "done"], ["close_hand", "done"], ["wait_sig", "done"],
            ["open_hand", "done"], ["relax_hand", "done"]]
        assert lines[1].endswith(" 0") and lines[2].endswith(" -1,0,-1")
        code, out, err = await run_send(sim.port, "signal:1001")
        assert code == 1 and len(out.splitlines()) == 1 and "error" in out and str(int(ErrorCode.ILLEGAL_SIGNAL)) in out
        assert "input" in err and "Traceback" not in err


@pytest.mark.timeout(30)
async def test_client_commands_and_the_inputs_test_api():
    async with running_sim(time_scale=10) as sim, RobotClient(sim.host, sim.port) as robot:
        res = await robot.cmdexec(Signal(3), Sig(3, 1003))
        assert Sig.states(res.messages[-1].ack) == (True, False)
        sim.controller.io.set_input(1003, True, sim.now())      # a sensor sees a part
        res = await robot.cmdexec(WaitSig(1003, 1), Sig(1003))
        assert Sig.states(res.messages[-1].ack) == (True,)
        with pytest.raises(CommandError) as info:
            await robot.cmdexec(WaitSig(1004, 0.2))
        assert info.value.code == ErrorCode.SIGNAL_TIMEOUT
        # a missed pick is visible: nothing between the fingers, so the closed-fully switch comes on
        await robot.cmdexec(CloseHand(), WaitSig(1001, 1))
        await robot.cmdexec(OpenHand(), WaitSig(-1001, 1))
        sim.controller.io.set_part_in_hand(True, sim.now())
        res = await robot.cmdexec(CloseHand(), Sig(1001))
        assert Sig.states(res.messages[-1].ack) == (False,), "closed on a part: the switch stays off"


@pytest.mark.timeout(30)
async def test_state_stream_carries_io_and_every_change_once():
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.pubsub import Subscriber

    async with running_sim(time_scale=10, state_endpoint="tcp://127.0.0.1:0", state_rate_hz=200) as sim:
        async with Subscriber(sim.state_endpoint, topics=[ROBOT_STATE_TOPIC]) as sub, \
                RobotClient(sim.host, sim.port) as robot:
            await sub.recv()  # subscribed
            await robot.cmdexec(Signal(7, 2002), CloseHand(), WaitSig(1001, 2), Signal(-7))
            seen: list[tuple[int, bool]] = []
            times: list[float] = []
            st = RobotState.from_bytes((await sub.recv())[1])
            while not ((7, False) in seen and st.hand == "closed"):
                seen += [(c.signal, c.on) for c in st.changes]
                times += [c.t_s for c in st.changes]
                st = RobotState.from_bytes((await sub.recv())[1])
            seen += [(c.signal, c.on) for c in st.changes]
            assert seen == [(7, True), (2002, True), (2, True), (1001, True), (7, False)], "each change once, in order"
            assert times == sorted(times)
            assert 7 not in st.outputs_on and 2 in st.outputs_on and st.inputs_on == (1001,) and st.soft_on == (2002,)


@pytest.mark.timeout(30)
async def test_pick_with_io_example_runs():
    from pathlib import Path

    example = Path(__file__).resolve().parents[2] / "examples" / "pick_with_io.py"
    proc = await asyncio.create_subprocess_exec(sys.executable, str(example), stdout=asyncio.subprocess.PIPE,
                                                stderr=asyncio.subprocess.PIPE)
    out, err = await proc.communicate()
    assert proc.returncode == 0, err.decode()
    assert out.decode().splitlines() == ["picked and placed", "done output, closed-fully switch: (True, False)",
                                         "missed the part"]
