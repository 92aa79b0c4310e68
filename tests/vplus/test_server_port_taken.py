"""The shipped V+ server whose port cannot be opened ends whole, as it would on a controller: the reader says so and
halts the server, so the executor (and the state task) do not run on serving nobody. On the emulator without the
CLI (which also dies on a port it could not bind), with a real port held by someone else."""

from __future__ import annotations

import asyncio
import socket
from pathlib import Path

import pytest

from aioadept.sim.controller import Controller
from aioadept.vplus import Emulator, RealClock
from aioadept.vplus.emulator import make_robot
from aioadept.vplus.iodev import Network

ROOT = Path(__file__).resolve().parents[2] / "vplus"
SERVER = [ROOT / f for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2", "rsstate.V2")]


@pytest.mark.timeout(30)
@pytest.mark.parametrize("which", ["main port", "stop port"])
async def test_a_port_that_cannot_be_opened_ends_every_task_of_the_server(which):
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        taken = held.getsockname()[1]
        ports = {1234: taken, 1235: 0, 1236: 0} if which == "main port" else {1234: 0, 1235: taken, 1236: 0}
        emu = Emulator.load(*SERVER, strict=True, clock=RealClock(),
                            robot=make_robot(Controller(time_scale=20.0)))
        emu.rt.devices = Network("127.0.0.1", ports)
        emu.globals["rs.stream"] = True
        stop = asyncio.Event()
        emu.execute(0, "rs.main")
        serving = asyncio.create_task(emu.serve(stop))
        try:
            async with asyncio.timeout(10):
                while any(t.state == "running" for t in emu.rt.tasks.values()):
                    await asyncio.sleep(0.05)
        finally:
            stop.set()
            await serving
    assert any("FOPEN failed" in line for line in emu.console)
    assert any("[rs] not serving: the server ends" in line for line in emu.console)
    assert not emu.globals["rs.run"]
