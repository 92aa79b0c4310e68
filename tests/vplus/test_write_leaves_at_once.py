"""A WRITE to a TCP connection leaves at once when it is the first record to that connection since the LUN's last
READ and no input waits: a server's ack of a lone line does not wait for the rest of the reader's loop. What the
program writes after it until its next READ (the acks of the other lines one READ brought) is sent together, in
one send, as before (docs/vplus.md, Performance, seventh round). In-process emulator, real TCP on 127.0.0.1."""

from __future__ import annotations

import asyncio

from aioadept.vplus import Emulator, RealClock
from aioadept.vplus.iodev import Network

SERVER = """
.PROGRAM t()
	AUTO lun, h
	stage = 0
	ATTACH (lun, 4) "TCP"
	FOPEN (lun, 16) "/LOCAL_PORT 5000 /CLIENTS 1"
	DO
	    READ (lun, h, 0) $in
	UNTIL IOSTAT(lun) == 100
	READ (lun, h) $in
	WRITE (lun, h) "one"
	stage = 1
	WRITE (lun, h) "two"
	stage = 2
	WRITE (lun, h) "three"
	stage = 3
	WAIT.EVENT , 0.05
	stage = 4
.END
"""


async def test_the_first_record_after_a_read_leaves_before_the_next_statement_the_rest_together() -> None:
    listening: asyncio.Future[int] = asyncio.get_running_loop().create_future()
    emu = Emulator.from_source(SERVER, filename="w.V2", robot=False, strict=True, clock=RealClock())
    net = emu.rt.devices = Network("127.0.0.1", {5000: 0}, lambda v, h, p: listening.set_result(p))
    sends: list[tuple[float, bytes]] = []          # (the program's stage when the bytes were sent, the bytes)
    send = net._send

    def recording_send(tr, parts: list[bytes]) -> None:
        sends.append((emu.rt.globals["stage"], b"".join(parts)))
        send(tr, parts)

    net._send = recording_send                      # type: ignore[method-assign]
    stop = asyncio.Event()
    emu.execute(0, "t")
    serving = asyncio.ensure_future(emu.serve(stop))
    try:
        async with asyncio.timeout(30):
            reader, writer = await asyncio.open_connection("127.0.0.1", await listening)
            writer.write(b"x\r\n")
            got = [await reader.readuntil(b"\r\n") for _ in range(3)]
            while emu.task(0).state == "running":
                await asyncio.sleep(0.01)
            writer.close()
    finally:
        stop.set()
        await serving
    assert emu.task(0).state == "done", emu.console
    assert got == [b"one\r\n", b"two\r\n", b"three\r\n"]
    assert sends == [(0.0, b"one\r\n"), (3.0, b"two\r\nthree\r\n")]
