"""``aioadept send sig`` with no signal numbers: the error names the skill called, ``sig`` (it said ``signal needs at
least one signal number``, the output skill's words); ``signal`` still names ``signal``. A real ``aioadept sim``
process and the real ``aioadept send`` over TCP."""

from __future__ import annotations

import asyncio
import sys

import pytest

from aioadept.testing.nodes import running_node


@pytest.mark.timeout(60)
async def test_sig_without_numbers_names_sig():
    async with running_node("sim", "--port", "0", "--state-endpoint", "none", expect_clean_exit=False) as node:
        said = {}
        for skill in ("sig", "signal"):
            proc = await asyncio.create_subprocess_exec(
                sys.executable, "-m", "aioadept", "send", "--port", str(node.ready["port"]), "--stop-port", "none",
                skill, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
            _out, err = await asyncio.wait_for(proc.communicate(), 30)
            assert proc.returncode == 1, err.decode()
            said[skill] = err.decode()
    assert "sig needs at least one signal number" in said["sig"] and "signal needs" not in said["sig"]
    assert "signal needs at least one signal number" in said["signal"]
