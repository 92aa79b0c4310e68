"""``aioadept ros2 --state-endpoint bogus`` is a bad option like any other: one line naming the option, exit 2,
before any Zenoh session is opened (it exited 1 after trying to reach a router)."""

from __future__ import annotations

import subprocess
import sys

import pytest


@pytest.mark.timeout(60)
@pytest.mark.parametrize("endpoint", ["bogus", "tcp:/127.0.0.1", "zenoh:"])
def test_a_bad_state_endpoint_is_one_line_and_exit_2(endpoint):
    res = subprocess.run([sys.executable, "-m", "aioadept", "ros2", "--state-endpoint", endpoint,
                          "--zenoh-connect", "tcp/127.0.0.1:9"], capture_output=True, text=True, timeout=30)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    assert lines[0].startswith("aioadept ros2: --state-endpoint:") and "Zenoh session" not in lines[0]
