"""A dead client's wait ends with it, on both backends.

A client sends ``wait_sig:1002,15`` (input 1002 stays off) and disconnects, with a FIN or a reset, while the wait
runs. Its wait ends then and nothing of it is acked; another client's next command, which goes through the executor,
is served at once. (The V+ server once held the executor in the dead client's wait: the next command was served
about 14 s later.)
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import struct

import pytest

from aioadept.protocol import Status


@pytest.mark.parametrize("how", ["fin", "rst"])
@pytest.mark.timeout(90)
async def test_a_client_that_goes_while_its_wait_sig_waits_does_not_hold_the_others(server, how):
    a = await server.connect()
    await a.send("kd000001:hello")
    assert (await a.ack()).status is Status.DONE
    await a.send("kd000002:wait_sig:1002,15", "kd000003:set_speed:50")  # the second never runs: a is gone
    await asyncio.sleep(0.5)  # the wait runs
    if how == "rst":
        sock = a.writer.get_extra_info("socket")
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        a.writer.transport.abort()
    else:
        await a.close()
    await asyncio.sleep(0.2)
    b = await server.connect()
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    await b.send("ke000001:set_speed:20")  # through the executor (not a query the reader answers itself)
    ack = await b.ack(20)
    took = loop.time() - t0
    assert (ack.id, ack.status) == ("ke000001", Status.DONE), ack
    # generous for a loaded CI machine: the dead client's wait had 14 s left
    assert took < 3.0, f"another client's command was served {took:.1f} s after the waiter went"
    await b.close()
