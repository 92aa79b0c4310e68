"""``aioadept vplus dap --listen`` driven by Microsoft's own DAP test client (``DebugClient`` of the npm package
``@vscode/debugadapter-testsupport``, pinned with its tree in tests/integration/dap_node/package-lock.json), from a
node script run by pytest: the issue's scenario on the shipped V+ server (vplus/), a real TCP client sending
``here``. Skipped with a warning where node or npm is missing."""

from __future__ import annotations

import asyncio
import json
import shutil
import sys
from pathlib import Path

import pytest
from dapclient import MODULES, VPLUS, first_statement
from npmtree import npm_tree

from aioadept.ports import free_port

pytestmark = pytest.mark.timeout(90)
HERE = Path(__file__).resolve().parent / "dap_node"


@pytest.fixture(scope="module")
def node_script() -> Path:
    return npm_tree(HERE, "dap-node", what="VPLUS DAP DEBUGCLIENT TEST") / "vplus_dap.mjs"


async def test_microsofts_debug_client_runs_the_scenario_against_the_adapter(node_script):
    dap_port = free_port()
    adapter = await asyncio.create_subprocess_exec(sys.executable, "-m", "aioadept", "vplus", "dap", "--listen",
                                                   f"127.0.0.1:{dap_port}", stdout=asyncio.subprocess.PIPE)
    try:
        assert adapter.stdout is not None
        ready = await asyncio.wait_for(adapter.stdout.readline(), 30)
        assert ready.decode().strip() == f"LISTENING 127.0.0.1:{dap_port}"
        cfg = {"modules": MODULES, "rserver": str(VPLUS / "rserver.V2"), "port": free_port(),
               "stopPort": free_port(), "l0": first_statement(VPLUS / "rserver.V2", "rs.online")}
        node = await asyncio.create_subprocess_exec(shutil.which("node"), str(node_script), str(dap_port),
                                                    json.dumps(cfg), cwd=node_script.parent,
                                                    stdout=asyncio.subprocess.PIPE)
        out, _ = await asyncio.wait_for(node.communicate(), 60)
        result = json.loads(out.decode().strip().splitlines()[-1])
        assert result == {"ok": True}, result
        assert await asyncio.wait_for(adapter.wait(), 10) == 0      # the session over, the adapter ends
    finally:
        if adapter.returncode is None:
            adapter.kill()
            await adapter.wait()
