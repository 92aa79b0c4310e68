"""A node's log that the disk refuses (``/dev/full``: every flush fails with ENOSPC) is cut short with one warning;
the node still starts, its READY line is read, its output is still drained and kept for error messages, and it
stops cleanly: a full disk during a run never ends the run through a node's log."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from aioadept.apps.processes import NodeProcess

pytestmark = pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this machine")


@pytest.mark.timeout(60)
async def test_a_node_whose_log_meets_a_full_disk_starts_runs_and_stops(caplog):
    caplog.set_level(logging.WARNING, logger="aioadept.apps.processes")
    node = NodeProcess("sim", ["sim", "--port", "0", "--stop-port", "none", "--state-endpoint", "none"],
                       log_path=Path("/dev/full"))
    async with node:
        assert node.ready["port"].isdigit(), node.ready
        assert node.returncode is None
    assert node.returncode is not None
    assert any(ln.startswith("READY") for ln in node.tail().replace("  [sim] ", "").splitlines()), node.tail()
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "/dev/full is cut short" in warnings[0] and "No space left" in warnings[0], warnings
