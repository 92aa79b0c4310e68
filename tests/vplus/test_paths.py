"""Paths of the emulator not covered elsewhere: PAUSE/PROCEED, PROMPT, CYCLE.END, data sections, ABORT and KILL
of a live task, and a client FOPEN (/REMOTE_PORT) against a real asyncio server."""

from __future__ import annotations

import asyncio

import pytest

from aioadept.vplus import Emulator, RealClock
from aioadept.vplus.iodev import Network


def test_pause_stops_the_task_until_proceed(emu_of):
    emu = emu_of(".PROGRAM p()\n\tx = 1\n\tPAUSE\n\tx = 2\n.END\n")
    emu.execute(1, "p")
    emu.run(1.0)
    assert emu.globals["x"] == 1.0 and emu.task(1).state == "running"
    assert "[1] (PAUSED) p, line 3" in emu.console
    emu.proceed(1)
    emu.run(0.1)
    assert emu.globals["x"] == 2.0 and emu.task(1).state == "done"


def test_prompt_types_its_text_and_reads_a_number_and_a_string(emu_of):
    emu = emu_of('.PROGRAM p()\n\tPROMPT "n? ", n\n\tPROMPT "name? ", $s\n.END\n')
    emu.execute(1, "p")
    emu.run(0.5)
    assert emu.task(1).state == "running"          # waiting for input
    emu.feed_input("42", "viper")
    emu.run(0.5)
    assert (emu.globals["n"], emu.globals["$s"]) == (42.0, "viper")


def test_cycle_end_ends_a_looping_task_after_its_current_cycle(emu_of):
    emu = emu_of(".PROGRAM p()\n\tn = n+1\n\tWAIT.EVENT 0, 0.1\n.END\n.PROGRAM q()\n\tCYCLE.END 1\n.END\n")
    emu.globals["n"] = 0
    emu.execute(1, "p", cycles=-1)                # for ever
    emu.run(0.35)
    assert emu.globals["n"] == 4.0 and emu.task(1).state == "running"
    emu.call("q", task=2)
    emu.run(1.0)
    assert emu.task(1).state == "done" and emu.globals["n"] == 4.0


def test_data_sections_load_into_globals(emu_of):
    emu = emu_of(""".PROGRAM p()
	x = r1+d1
.END
.LOCATIONS
loc1 100 200 300 0 180 0
.END
.PRECISION POINTS
#pp 10 -90 180 0 90 0
.END
.REALS
r1 1.5
arr[2] 7
.END
.DOUBLES
d1 0.1
.END
.STRINGS
$greet "hello, V+"
.END
""")
    g = emu.globals
    assert g["arr"] == {2: 7.0} and g["$greet"] == "hello, V+" and g["d1"] == 0.1
    assert tuple(g["#pp"].joints_deg) == (10, -90, 180, 0, 90, 0)
    assert (g["loc1"].to_pose().x, g["loc1"].to_pose().z) == pytest.approx((100, 300))
    emu.call("p")
    assert g["x"] == pytest.approx(1.6)


def test_abort_and_kill_a_live_task(emu_of):
    emu = emu_of(".PROGRAM spin()\n\tWHILE TRUE DO\n\t\tn = n+1\n\tEND\n.END\n"
                 ".PROGRAM stopper()\n\tABORT 1\n.END\n.PROGRAM killer()\n\tKILL 1\n.END\n")
    emu.globals["n"] = 0
    emu.execute(1, "spin")
    emu.run(0.01)
    assert emu.task(1).state == "running" and emu.globals["n"] > 0
    emu.call("stopper", task=2)
    n = emu.globals["n"]
    emu.run(0.05)
    assert emu.task(1).state == "aborted" and emu.globals["n"] == n
    assert "[1] (task 1) aborted" in emu.console
    emu.execute(1, "spin")
    emu.run(0.01)
    emu.call("killer", task=2)
    assert emu.task(1) is None                     # KILL removes the task
    emu.execute(1, "spin")                         # the task number is free again
    assert emu.task(1).state == "running"


@pytest.mark.timeout(20)
async def test_client_fopen_remote_port_talks_to_a_real_server():
    got: list[bytes] = []

    async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        got.append(await reader.readuntil(b"\n"))
        writer.write(b"pong\r\n")
        await writer.drain()
        writer.close()

    server = await asyncio.start_server(serve, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    emu = Emulator.from_source(f""".PROGRAM cli()
	AUTO lun, h
	ATTACH (lun, 4) "TCP"
	FOPEN (lun, 16) "/REMOTE_IP 127.0.0.1 /REMOTE_PORT {port}"
	st.open = IOSTAT(lun)
	READ (lun, h, 0) $in
	st.conn = IOSTAT(lun)
	WRITE (lun, h) "ping"
	$reply = ""
	WHILE (IOSTAT(lun) <> 101) DO
	    READ (lun, h, 0) $in
	    IF IOSTAT(lun) == 1 THEN
	        $reply = $reply+$in
	    END
	END
	FCLOSE (lun)
	DETACH (lun)
.END
""", filename="c.V2", robot=False, strict=True, clock=RealClock())
    emu.rt.devices = Network()
    stop = asyncio.Event()
    emu.execute(0, "cli")
    serving = asyncio.ensure_future(emu.serve(stop))
    try:
        async with asyncio.timeout(10):
            while emu.task(0).state == "running":
                await asyncio.sleep(0.01)
    finally:
        stop.set()
        await serving
        server.close()
    assert emu.task(0).state == "done", emu.console
    assert (emu.globals["st.open"], emu.globals["st.conn"]) == (1.0, 100.0)
    assert got == [b"ping\r\n"] and emu.globals["$reply"] == "pong\r\n"
