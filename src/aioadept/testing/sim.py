"""``running_sim()``: the simulated controller served in-process on an ephemeral port, for tests and notebooks.

    async with running_sim(instant=True) as sim:
        async with RobotClient(sim.host, sim.port) as robot:
            ...
        sim.controller.joints_deg      # inspect the pure controller

Options are the fields of :class:`aioadept.sim.server.SimOptions` (port 0 and no state stream unless given) plus
the fault switches ``ack_delay_s``, ``drop_after`` and ``silent``.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from aioadept.sim.server import Faults, SimOptions, SimServer

__all__ = ["running_sim"]


@asynccontextmanager
async def running_sim(*, ack_delay_s: float = 0.0, drop_after: int | None = None, silent: bool = False,
                      **options: Any) -> AsyncIterator[SimServer]:
    """Start a :class:`SimServer` on 127.0.0.1, port 0; yield it (``host``, ``port``, ``controller``, ...)."""
    options.setdefault("port", 0)
    options.setdefault("state_endpoint", None)
    if "faults" not in options:
        options["faults"] = Faults(ack_delay_s=ack_delay_s, drop_after=drop_after, silent=silent)
    sim = SimServer(SimOptions(**options))
    await sim.start()
    try:
        yield sim
    finally:
        await sim.close()
