"""No wrist flips from tiny commands, through the real sim over TCP.

A :class:`SimServer` on 127.0.0.1:0 (instant motion, no state stream) driven by :class:`RobotClient`; the joints
are read from the ``here`` ack's trailing joint field (docs/protocol.md) after each command.
"""

from __future__ import annotations

import contextlib

import pytest

from aioadept import Here, MoveJoints, MoveRelTool, MoveRelWorld, MoveToolZ
from aioadept.client import RobotClient
from aioadept.errors import CommandError
from aioadept.protocol import ErrorCode
from aioadept.robots.viper_s850 import HOME_JOINTS_DEG
from aioadept.sim.server import SimOptions, SimServer

PAPER_INIT_MOVE = tuple(a + d for a, d in zip(HOME_JOINTS_DEG, (-90, 60, 30, -90, 0, 0), strict=True))


@contextlib.asynccontextmanager
async def robot_on_sim(joints=HOME_JOINTS_DEG):
    sim = SimServer(SimOptions(port=0, state_endpoint=None, instant=True, joints_deg=tuple(joints)))
    await sim.start()
    try:
        async with RobotClient(sim.host, sim.port, connect_timeout_s=2.0, ack_timeout_s=5.0) as robot:
            yield robot
    finally:
        await sim.close()


async def joints(robot: RobotClient) -> tuple[float, ...]:
    ack = (await robot.cmdexec(Here())).messages[0].ack
    assert ack.extra, "the sim's here ack carries the joint field"
    values = tuple(float(v) for v in ack.extra[-1].split(","))
    assert len(values) == 6
    return values


def max_move(a, b) -> float:
    return max(abs(x - y) for x, y in zip(a, b, strict=True))


@pytest.mark.timeout(30)
async def test_paper_focus_steps_keep_the_wrist_still():
    async with robot_on_sim() as robot:
        await robot.cmdexec(MoveJoints(PAPER_INIT_MOVE))
        q = await joints(robot)
        assert max_move(q, PAPER_INIT_MOVE) < 1e-3
        for k in range(40):
            dz = (0.5 + (k % 5) * 0.5) * (1 if k < 25 else -1)  # 0.5 .. 2.5 mm, forward then back
            await robot.cmdexec(MoveToolZ(dz))
            q2 = await joints(robot)
            assert abs(q2[3] - q[3]) <= 1.0 and abs(q2[5] - q[5]) <= 1.0, (k, q, q2)
            assert max_move(q2, q) <= 2.0
            q = q2


@pytest.mark.timeout(30)
async def test_tool_step_next_to_the_wrist_singularity_does_not_flip():
    # Before the fix this 2 mm move_rel_tool turned J4 and J6 by 180 deg.
    start = (0.0, -90.0, 180.0, 0.0, 0.2, 0.0)
    async with robot_on_sim(start) as robot:
        await robot.cmdexec(MoveRelTool((2, 0, 0, 0, 0, 0)))
        q = await joints(robot)
        assert max_move(q, start) < 1.0, q
        # Now 0.08 deg off the singularity: moving 0.5 mm sideways would need J4 to turn 21 deg. Refused, whole.
        with pytest.raises(CommandError) as info:
            await robot.cmdexec(MoveRelWorld((0, 0.5, -0.5, 0, 0, 0)))
        assert info.value.code == ErrorCode.JOINT_JUMP and "singularity" in info.value.message
        assert max_move(await joints(robot), q) < 1e-3
        # Straight along the tool axis is fine.
        await robot.cmdexec(MoveToolZ(-1.5))
        assert max_move(await joints(robot), q) < 1.0


@pytest.mark.timeout(30)
async def test_a_joint_jump_is_refused_with_an_error_ack_and_nothing_moves():
    # J6 at 359.5: a 1 deg turn of the tool would unwind J6 by a whole revolution (before the fix: it did).
    start = (0.0, -90.0, 180.0, 0.0, 90.0, 359.5)
    async with robot_on_sim(start) as robot:
        with pytest.raises(CommandError) as info:
            await robot.cmdexec(MoveRelTool((0, 0, 0, 0, 0, 1)))
        assert info.value.code == ErrorCode.JOINT_JUMP
        assert "J6" in info.value.message
        assert max_move(await joints(robot), start) < 1e-3  # nothing moved
        # The connection still works, and the other way round is an ordinary small move.
        await robot.cmdexec(MoveRelTool((0, 0, 0, 0, 0, -1)))
        q = await joints(robot)
        assert q[5] == pytest.approx(358.5, abs=1e-3) and max_move(q, start) <= 1.0 + 1e-3
