"""A Zenoh session that cannot open is one line naming the address and a likely fix, without Zenoh's Rust source
paths (``at /root/.cargo/.../orchestrator.rs:388.``): real ``aioadept sim --transport zenoh`` processes, a router
address where nothing listens and a listen port another socket holds (both on 127.0.0.1)."""

from __future__ import annotations

import importlib.util
import socket
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(importlib.util.find_spec("zenoh") is None,
                                reason="the [zenoh] extra (eclipse-zenoh) is not installed")


def sim(*args: str) -> list[str]:
    res = subprocess.run([sys.executable, "-m", "aioadept", "sim", "--port", "0", "--state-endpoint", "none",
                          "--transport", "zenoh", *args], capture_output=True, text=True, timeout=40)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 1 and len(lines) == 1, res.stderr
    assert ".rs:" not in lines[0] and ".cargo" not in lines[0], lines[0]
    return lines


@pytest.mark.timeout(60)
def test_no_router_at_the_address_names_it_and_how_to_start_one():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # free a moment ago, and nothing listens: bound, not listening
        (line,) = sim("--zenoh-connect", f"tcp/127.0.0.1:{port}")
    assert f"cannot open the Zenoh session: no router answers at tcp/127.0.0.1:{port}" in line
    assert "--zenoh-listen" in line and "credentials" in line


@pytest.mark.timeout(60)
def test_a_listen_port_in_use_says_so():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        (line,) = sim("--zenoh-listen", f"tcp/127.0.0.1:{port}")
    assert f"cannot open the Zenoh session: cannot listen on tcp/127.0.0.1:{port}: the port is in use" in line
