"""A node started by an app (demo, experiment) dies with it, even when the app is killed with SIGKILL."""

from __future__ import annotations

import asyncio
import os
import signal
import sys
import textwrap

import pytest

pytestmark = [pytest.mark.timeout(60),
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux only")]

APP = textwrap.dedent("""
    import asyncio, sys
    from aioadept.apps.processes import NodeProcess

    async def main():
        node = NodeProcess("sim", ["sim", "--port", "0", "--state-endpoint", "none"])
        await node.start()
        print(node.proc.pid, flush=True)
        await asyncio.Event().wait()

    asyncio.run(main())
""")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie (dead, not yet reaped by init) counts as gone.
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


async def test_a_sigkilled_app_leaves_no_node_running():
    app = await asyncio.create_subprocess_exec(sys.executable, "-c", APP, stdout=asyncio.subprocess.PIPE)
    try:
        async with asyncio.timeout(30):
            line = await app.stdout.readline()
        node_pid = int(line)
        assert _alive(node_pid)
        app.send_signal(signal.SIGKILL)  # no cleanup code of the app runs
        await app.wait()
        loop = asyncio.get_running_loop()
        deadline = loop.time() + 10
        while _alive(node_pid) and loop.time() < deadline:
            await asyncio.sleep(0.05)
        assert not _alive(node_pid), "the sim outlived the app that started it"
    finally:
        if app.returncode is None:
            app.kill()
            await app.wait()
