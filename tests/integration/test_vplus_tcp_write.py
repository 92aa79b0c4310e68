"""The V+ emulator's WRITE on a TCP connection, against real peers.

V+ output waits until the record is out (V+ Language User's Guide, "Output Wait Modes"); over TCP that is while the
peer does not read. The emulator must never wait for ever: when the peer resets the connection, the waiting WRITE
ends with an error IOSTAT and the program goes on. The no-wait form (``/N``) returns at once and ``IOSTAT(lun, 3)``
reports its completion; ``FCLOSE (lun, handle)`` closes one client of a server.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import struct
from pathlib import Path

import pytest

from aioadept.testing.nodes import running_node

PROGRAM = """.PROGRAM wtest()
; Serve one client: write 100 000 lines of 100 characters (10 MB) with a waiting WRITE (the peer never reads), then say how
; the WRITEs ended. Then a no-wait WRITE to the next client and its completion, and FCLOSE of that client.
	AUTO lun, h, i, st, bad
	AUTO $s
	ATTACH (lun, 4) "TCP"
	FOPEN (lun, 16) "/LOCAL_PORT 1234 /CLIENTS 4 /BUFFER_SIZE 2048"
	READ (lun, h, 0) $s
	TYPE "connected ", IOSTAT(lun)
	$s = "xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx"
	$s = $s+$s
	bad = 0
	FOR i = 1 TO 100000
	    IF bad == 0 THEN
	        WRITE (lun, h) $s
	        st = IOSTAT(lun)
	        IF st < 0 THEN
	            bad = st
	        END
	    END
	END
	TYPE "write ended ", bad
	READ (lun, h, 0) $s
	WHILE IOSTAT(lun) <> 100 DO
	    READ (lun, h, 0) $s
	END
	WRITE (lun, h) "hello", /N
	TYPE "nowait ", IOSTAT(lun, 3)
	FCLOSE (lun, h)
	TYPE "fclose ", IOSTAT(lun)
	WAIT.EVENT 1, 5
.END
"""


def _reset(sock: socket.socket) -> None:
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    sock.close()


async def _log_has(log: Path, text: str, timeout_s: float) -> bool:
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout_s
    while loop.time() < end:
        if text in log.read_text():
            return True
        await asyncio.sleep(0.05)
    return False


@pytest.mark.timeout(60)
async def test_a_write_to_a_peer_that_resets_fails_instead_of_waiting_for_ever(tmp_path):
    src = tmp_path / "wtest.V2"
    src.write_text(PROGRAM)
    log = tmp_path / "sim.log"
    async with running_node("sim", "--vplus", str(src), "--run", "wtest", "--map-port", "1234=0",
                            "--state-endpoint", "none", log_path=log, expect_clean_exit=False) as node:
        port = int(node.ready["port"])
        peer = socket.socket()
        peer.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        peer.connect(("127.0.0.1", port))
        assert await _log_has(log, "connected 100", 10)
        await asyncio.sleep(4.0)  # the WRITEs have filled every buffer and the program waits
        assert "write ended" not in log.read_text(), "10 MB went out to a peer that never read"
        _reset(peer)
        assert await _log_has(log, "write ended -", 10), log.read_text()[-500:]
        # a no-wait WRITE returns at once and is complete as soon as its bytes are taken; FCLOSE of one handle
        with socket.create_connection(("127.0.0.1", port)) as second:
            second.settimeout(10)
            data = b""
            while len(data) < 7 and (chunk := second.recv(100)):
                data += chunk
            assert data == b"hello\r\n"
            assert await _log_has(log, "nowait 1", 10)
            assert await _log_has(log, "fclose 1", 10)
            with contextlib.suppress(ConnectionResetError):
                assert second.recv(100) == b""  # the server closed it
