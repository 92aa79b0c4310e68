"""The emulator's small TCP buffers (``aioadept sim --tcp-send-buffer BYTES``, ``Network.send_buffer``): a peer
that does not read backs a V+ program's no-wait output up after a few KiB, as on a controller, instead of after
the megabytes a loopback socket's buffer grows to; the default is unchanged (docs/vplus.md)."""

from __future__ import annotations

import asyncio
import socket

import pytest

from aioadept.cli.sim import main as sim_main
from aioadept.vplus import Emulator, RealClock
from aioadept.vplus.iodev import Network

LINE = 100        # characters a WRITE sends, CR LF added
CAP = 20000       # WRITEs at most (2 MB): the default's buffers take more than 64 KiB, far less than this

WRITER = f"""
.PROGRAM t()
	AUTO lun, h
	GLOBAL sent, st3
	ATTACH (lun, 4) "TCP"
	FOPEN (lun, 16) "/LOCAL_PORT 5000 /CLIENTS 1"
	DO
	    READ (lun, h, 0) $in
	UNTIL IOSTAT(lun) == 100
	$s = "{"x" * LINE}"
	sent = 0
	DO
	    WRITE (lun, h) $s, /N
	    sent = sent+1
	    st3 = IOSTAT(lun, 3)
	    IF st3 == 0 THEN
	        ; not out yet may be this burst's WRITEs not sent yet: backed up only if still not out a while later
	        WAIT.EVENT , 0.05
	        st3 = IOSTAT(lun, 3)
	    END
	UNTIL (st3 == 0) OR (sent >= {CAP})
.END
"""


async def _bytes_out_before_backed_up(send_buffer: int | None) -> int:
    """Run WRITER against a peer that connects with a small receive window and never reads: the bytes the
    program wrote until its last no-wait WRITE stayed not out (IOSTAT(lun, 3) = 0) for 50 ms."""
    listening: asyncio.Future[int] = asyncio.get_running_loop().create_future()
    emu = Emulator.from_source(WRITER, filename="w.V2", robot=False, strict=True, clock=RealClock())
    emu.rt.devices = Network("127.0.0.1", {5000: 0}, lambda v, h, p: listening.set_result(p),
                             send_buffer=send_buffer)
    stop = asyncio.Event()
    emu.execute(0, "t")
    serving = asyncio.ensure_future(emu.serve(stop))
    sock = socket.socket()
    try:
        async with asyncio.timeout(30):
            port = await listening
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connect: its window stays small
            sock.setblocking(False)
            await asyncio.get_running_loop().sock_connect(sock, ("127.0.0.1", port))
            while emu.task(0).state == "running":
                await asyncio.sleep(0.01)
    finally:
        sock.close()
        stop.set()
        await serving
    assert emu.task(0).state == "done", emu.console
    g = emu.globals
    assert g["st3"] == 0 or g["sent"] == CAP, g
    return int(g["sent"]) * (LINE + 2)


async def test_a_small_send_buffer_backs_the_output_up_after_a_few_kib_and_the_default_does_not():
    small = await _bytes_out_before_backed_up(4096)
    # 4096 here, the kernel's doubled SO_SNDBUF (8 KiB) and the peer's 4 KiB window: well under 64 KiB
    assert small < 32 * 1024, small
    default = await _bytes_out_before_backed_up(None)
    # the emulator's own output buffer alone holds 64 KiB before a WRITE is not out
    assert default > 64 * 1024, default


@pytest.mark.parametrize("argv, says", [
    (["--tcp-send-buffer", "4096"], "need --vplus"),
    (["--vplus", "x.V2", "--run", "t", "--tcp-send-buffer", "10"], "--tcp-send-buffer 10: out of range"),
])
def test_the_option_is_refused_in_one_line_without_vplus_or_out_of_range(argv, says, capsys):
    with pytest.raises(SystemExit) as exc:
        sim_main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert says in err[-1] and "Traceback" not in "\n".join(err), err
