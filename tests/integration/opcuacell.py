"""A cell for the OPC UA tests: ``aioadept sim`` publishing its state and ``aioadept opcua`` following it, both real
processes on 127.0.0.1, the OPC UA server on a free port."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass
from pathlib import Path

from aioadept.ports import free_port
from aioadept.testing.nodes import NodeProcess, running_node

ROBOTICS_NS = "http://opcfoundation.org/UA/Robotics/"
TARGET = [30.0, -80.0, 170.0, 10.0, 60.0, -20.0]


@dataclass
class Cell:
    sim: NodeProcess
    opcua: NodeProcess
    url: str

    @property
    def robot_port(self) -> int:
        return int(self.sim.ready["port"])


@asynccontextmanager
async def opcua_cell(tmp_path: Path, *opcua_args: str) -> AsyncIterator[Cell]:
    async with running_node("sim", "--port", "0", "--state-rate", "50", "--state-endpoint", "tcp://127.0.0.1:0",
                            log_path=tmp_path / "sim.log") as sim:
        url = f"opc.tcp://127.0.0.1:{free_port()}"
        async with running_node("opcua", "--robot", f"127.0.0.1:{sim.ready['port']}", "--state-endpoint",
                                sim.ready["state"], "--endpoint", url, "--model", "Viper s850", "--category",
                                "ARTICULATED_ROBOT", *opcua_args,
                                log_path=tmp_path / "opcua.log", ready_timeout_s=60) as opcua:
            assert opcua.ready["opcua"] == url
            yield Cell(sim, opcua, url)
