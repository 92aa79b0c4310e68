"""A pick and place with digital I/O, against the simulated controller (or your robot server: replace the address).

Wait for the part-present sensor (an input), approach, open the gripper, go down, close it, and read the
gripper's closed-fully switch: on means it closed on nothing (a missed pick), off means it holds the part. Then
lift, place, open, and switch a "done" output for the PLC. Run: ``.venv/bin/python examples/pick_with_io.py``.
The same skills work against the V+ server on a controller (vplus/rsskills.V2); only the signal numbers are yours.
"""

from __future__ import annotations

import asyncio

from aioadept import (Break, CloseHand, MoveRelTool, MoveTo, OpenHand, SetSpeed, Sig, Signal, WaitSig)
from aioadept.client import RobotClient
from aioadept.testing.sim import running_sim

PART_PRESENT = 1003   # input: the feeder's sensor
CLOSED_FULLY = 1001   # input: the gripper's closed-fully switch (aioadept sim --hand, default 1,2,1001)
PICK_DONE = 5         # output: tells the PLC the part is gone
DOWN = (0, 0, 60, 0, 0, 0)   # 60 mm along the tool's z (down, tool pointing down)
UP = (0, 0, -60, 0, 0, 0)


async def pick_and_place(robot: RobotClient, pick: tuple, place: tuple) -> bool:
    """One cycle; False if the gripper closed on nothing."""
    await robot.cmdexec(WaitSig(PART_PRESENT, 10), SetSpeed(50), MoveTo(pick), OpenHand())
    await robot.cmdexec(MoveRelTool(DOWN), CloseHand())
    res = await robot.cmdexec(Sig(CLOSED_FULLY))
    if Sig.states(res.messages[-1].ack)[0]:
        await robot.cmdexec(OpenHand(), MoveRelTool(UP))
        return False
    await robot.cmdexec(MoveRelTool(UP), MoveTo(place), MoveRelTool(DOWN), OpenHand(), MoveRelTool(UP),
                        Signal(PICK_DONE), Break())
    return True


async def main() -> None:
    async with running_sim(time_scale=10) as sim, RobotClient(sim.host, sim.port, ack_timeout_s=30) as robot:
        io = sim.controller.io
        # the sim's world, by hand: a part arrives at the sensor and sits between the fingers once they close
        io.set_input(PART_PRESENT, True, sim.now())
        io.set_part_in_hand(True, sim.now())
        ok = await pick_and_place(robot, (450, 150, 350, 0, 180, 0), (450, -150, 350, 0, 180, 0))
        print("picked and placed" if ok else "missed the part")
        res = await robot.cmdexec(Sig(PICK_DONE, CLOSED_FULLY))
        print("done output, closed-fully switch:", Sig.states(res.messages[-1].ack))
        io.set_input(PART_PRESENT, False, sim.now())      # the part has left the sensor
        # a second cycle with no part between the fingers: the switch tells the miss
        io.set_input(PART_PRESENT, True, sim.now())
        io.set_part_in_hand(False, sim.now())
        ok = await pick_and_place(robot, (450, 150, 350, 0, 180, 0), (450, -150, 350, 0, 180, 0))
        print("picked and placed" if ok else "missed the part")


if __name__ == "__main__":
    asyncio.run(main())
