"""What the death tests of both backends (test_sim_death.py, test_vplus_death.py) share: recording a dying server's
state stream to its end."""

from __future__ import annotations

import asyncio

from aioadept.bus.messages import RobotState
from aioadept.bus.pubsub import Subscriber


async def record(sub: Subscriber, into: list[RobotState], proc: asyncio.subprocess.Process) -> None:
    """Every state sample until the process has exited and the stream is quiet."""
    while True:
        try:
            _, data = await asyncio.wait_for(sub.recv(), 0.5)
        except TimeoutError:
            if proc.returncode is not None:
                return
            continue
        into.append(RobotState.from_bytes(data))
