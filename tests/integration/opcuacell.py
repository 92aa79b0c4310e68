"""A cell for the OPC UA tests: ``aioadept sim`` publishing its state and ``aioadept opcua`` following it, both real
processes on 127.0.0.1, the OPC UA server on a free port."""

from __future__ import annotations

import asyncio
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


@dataclass
class FileCell:
    sims: dict[str, NodeProcess]
    opcua: NodeProcess
    url: str
    config: Path


@asynccontextmanager
async def opcua_cell_file(tmp_path: Path, models: dict[str, str], opcua_table: str, *opcua_args: str
                          ) -> AsyncIterator[FileCell]:
    """One ``aioadept sim`` per robot of ``models`` (its name: its --robot-model), each publishing its state, and
    ``aioadept opcua --config`` of a cell file with a ``[[robots]]`` entry for each and the ``[opcua]`` table
    ``opcua_table`` (its endpoint added: a free port)."""
    from contextlib import AsyncExitStack

    url = f"opc.tcp://127.0.0.1:{free_port()}"
    async with AsyncExitStack() as stack:
        started = await asyncio.gather(*(stack.enter_async_context(running_node(
            "sim", "--port", "0", "--state-rate", "50", "--state-endpoint", "tcp://127.0.0.1:0", "--robot-model",
            model, log_path=tmp_path / f"sim-{name}.log")) for name, model in models.items()))  # at once
        sims = dict(zip(models, started, strict=True))
        entries = "".join(f'\n[[robots]]\nname = "{name}"\nmodel = "{models[name]}"\nport = {sim.ready["port"]}\n'
                          f'state_endpoint = "{sim.ready["state"]}"\n' for name, sim in sims.items())
        config = tmp_path / "cell.toml"
        config.write_text(f'[opcua]\nendpoint = "{url}"\n{opcua_table}\n{entries}')
        opcua = await stack.enter_async_context(running_node("opcua", "--config", str(config), *opcua_args,
                                                             log_path=tmp_path / "opcua.log", ready_timeout_s=60))
        assert opcua.ready["opcua"] == url
        yield FileCell(sims, opcua, url, config)
