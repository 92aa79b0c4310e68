"""``aioadept sim --vplus`` with the server's port already taken: the program gets FOPEN's error
as on a controller, and the host, which serves the ports of its command line, says which port in one line and exits
1, instead of running on with no socket (the reader gone, the executor and the state stream looking alive)."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

from aioadept.ports import free_port

VPLUS = Path(__file__).resolve().parents[2] / "vplus"


@pytest.mark.timeout(60)
def test_the_shipped_server_on_a_taken_port_names_it_in_one_line_and_exits_1():
    port = free_port()
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", port))
        taken.listen()
        res = subprocess.run([sys.executable, "-m", "aioadept", "sim", "--instant",
                              "--vplus", str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"),
                              str(VPLUS / "rsconfig.V2"), "--run", "rs.main",
                              "--map-port", f"1234={port}", "--map-port", "1235=0", "--state-endpoint", "none"],
                             capture_output=True, text=True, timeout=30)
    assert res.returncode == 1, (res.stdout, res.stderr)
    err = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert err == [f"aioadept sim: V+ port 1234 (127.0.0.1:{port}) cannot be bound: already in use "
                   "(--map-port 1234=0 binds a free port)"]
    assert "READY" not in res.stdout and "[rs] FOPEN failed: *Device error*" in res.stdout
