"""Binary values in strings and byte input: $INTB/INTB, $LNGB/LNGB, $FLTB/FLTB, $DBLB/DBLB as the V+
Language Reference Guide defines them (big-endian, its own examples), GETC on a TCP connection and on a disk file,
and a binary message exchanged with a Python peer over real TCP."""

from __future__ import annotations

import asyncio
import struct

import pytest

from aioadept.vplus import Emulator, RealClock, VPlusError
from aioadept.vplus.iodev import Network


def run(body: str, **kw) -> Emulator:
    emu = Emulator.from_source(".PROGRAM t()\n" + body + "\n.END\n", filename="b.V2", strict=True, robot=False,
                               **kw)
    emu.call("t")
    return emu


def test_the_reference_guide_examples():
    g = run("\tGLOBAL DOUBLE dd\n"
            "\t$s = $LNGB(67*65536+12345)\n\ta = INTB($s)\n\tb = INTB($s, 3)\n"
            "\tc = LNGB($INTB(1)+$INTB(5))\n"
            "\td = FLTB($CHR(^H3F)+$CHR(^H80)+$CHR(0)+$CHR(0))\n"
            "\te = FLTB($CHR(^HC0)+$CHR(^H40)+$CHR(0)+$CHR(0))\n"
            "\tf = INTB($CHR(10)+$CHR(5))\n\tk = INTB($CHR(255)+$CHR(255))\n"
            "\tdd = LNGB($LNGB(-2147483648))").globals
    # "$LNGB(67*65536+12345) Returns the value $INTB(67)+$INTB(12345)"; LNGB(...) "Return the value 65541";
    # FLTB "Returns 1.0", "Returns -3.0"; INTB "Returns the value 2565", "-1"
    assert g["$s"] == "\x00C09" and (g["a"], g["b"], g["c"]) == (67.0, 12345.0, 65541.0)
    assert (g["d"], g["e"], g["f"], g["k"]) == (1.0, -3.0, 2565.0, -1.0)
    assert g["dd"] == -2147483648.0


def test_values_round_trip_at_a_position_and_doubles_keep_their_precision():
    g = run("\tGLOBAL DOUBLE dd, dl\n"
            "\t$m = $INTB(-2)+$LNGB(-70000)+$FLTB(1.5)+$DBLB(0.1)\n"
            "\ta = INTB($m, 1)\n\tb = LNGB($m, 3)\n\tc = FLTB($m, 7)\n\tdd = DBLB($m, 11)\n"
            "\tn = LEN($m)\n\tdl = LNGB($LNGB(16777217))\n\tr = LNGB($LNGB(16777217))").globals
    assert (g["a"], g["b"], g["c"], g["n"]) == (-2.0, -70000.0, 1.5, 18.0)
    assert g["dd"] == 0.1                              # 8 bytes: the double, not its single rounding
    assert g["dl"] == 16777217.0 and g["r"] == 16777216.0   # a REAL keeps 24 bits (the LNGB page says so)


@pytest.mark.parametrize("expr, what", [
    ("LNGB($INTB(1))", "LNGB: 4 bytes from character 1 are beyond the end"),
    ("INTB(\"abc\", 3)", "INTB: 2 bytes from character 3"),
    ("$LNGB(3000000000)", "outside -^H80000000..^H7FFFFFFF"),
    ("FLTB($CHR(^H7F)+$CHR(^H80)+$CHR(0)+$CHR(0))", "exponent 255"),
])
def test_what_the_pages_call_an_error_is_one(expr, what):
    with pytest.raises(VPlusError, match=what.replace("^", r"\^").replace("(", r"\(").replace("$", r"\$")):
        run(f"\tx = {expr}" if not expr.startswith("$") else f"\t$x = {expr}")


def test_getc_reads_a_disk_file_byte_by_byte_to_its_end(tmp_path):
    (tmp_path / "DATA.BIN").write_bytes(b"\x01\xffA")
    g = run('\tAUTO d\n\tATTACH (d, 4) "DISK"\n\tFOPENR (d) "DATA.BIN"\n'
            "\ta = GETC(d)\n\tb = GETC(d)\n\tc = GETC(d)\n\te = GETC(d)\n\ts = IOSTAT(d)\n\tFCLOSE (d)",
            disk_dir=tmp_path).globals
    assert (g["a"], g["b"], g["c"]) == (1.0, 255.0, 65.0)
    assert g["e"] == g["s"] == -504.0            # the end of the file: a negative code, in IOSTAT too


PEER = """.PROGRAM peer(port)
; Send a binary message (a 4-byte count, a float, a 2-byte code), then read the binary reply byte by byte with
; GETC: a no-wait GETC before the reply has come says so; the reply's end is the end of the connection.
	AUTO lun, h, i, c
	AUTO $r, $in
	ATTACH (lun, 4) "TCP"
	FOPEN (lun, 16) "/REMOTE_IP 127.0.0.1 /REMOTE_PORT ", port
	READ (lun, h, 0) $in
	nowait = GETC(lun, 1)
	WRITE (lun, h) $LNGB(-123456)+$FLTB(2.5)+$INTB(513), /S
	$r = ""
	FOR i = 1 TO 6
	    c = GETC(lun)
	    $r = $r+$CHR(c)
	END
	READ (lun, h, 0) $in
	$r = $r+$in
	n = LNGB($r)
	x = FLTB($r, 5)
	k = INTB($r, 9)
	last = GETC(lun)
	FCLOSE (lun)
	DETACH (lun)
.END
"""


async def test_a_binary_message_to_a_python_peer_and_its_binary_reply_read_with_getc():
    got: list[bytes] = []

    async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        msg = await reader.readexactly(10)
        got.append(msg)
        n, x, k = struct.unpack(">ifh", msg)
        reply = struct.pack(">ifh", n * 2, x + 0.25, k + 1)
        writer.write(reply[:6])            # in two parts: GETC waits for the second
        await writer.drain()
        await asyncio.sleep(0.05)
        writer.write(reply[6:])
        await writer.drain()
        await asyncio.sleep(0.05)
        writer.close()

    server = await asyncio.start_server(serve, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    emu = Emulator.from_source(PEER, filename="peer.V2", robot=False, strict=True, clock=RealClock())
    emu.rt.devices = Network()
    stop = asyncio.Event()
    emu.execute(0, "peer", port)
    serving = asyncio.ensure_future(emu.serve(stop))
    try:
        async with asyncio.timeout(10):
            while emu.task(0).state == "running":
                await asyncio.sleep(0.01)
    finally:
        stop.set()
        await serving
        server.close()
    g = emu.globals
    assert emu.task(0).state == "done", emu.console
    assert got == [struct.pack(">ifh", -123456, 2.5, 513)]
    assert (g["n"], g["x"], g["k"]) == (-246912.0, 2.75, 514.0)
    assert g["nowait"] == -526.0                 # mode not 0: *No data received* at once
    assert g["last"] == -504.0                   # the peer closed: the end of the data


def test_fcmnd_loads_and_says_at_run_time_that_it_is_not_emulated():
    emu = run('\tAUTO lun\n\tATTACH (lun, 4) "TCP"\n\tFCMND (lun, 7) "x"\n\ts = IOSTAT(lun)\n\tTYPE "after"')
    assert emu.globals["s"] == -500.0 and emu.console[-1].endswith("after")   # an I/O error: IOSTAT, the program goes on
    assert any("FCMND (20, 7) is not implemented by the emulator" in ln for ln in emu.console), emu.console


def test_a_transformation_round_trips_through_transb_by_column():
    emu = run("\tSET a = TRANS(10, -20, 30.5, 15, 40, -60)\n\t$s = \"xy\"+$TRANSB(a)\n"
              "\tSET b = TRANSB($s, 3)\n\tDECOMPOSE d[] = b\n\tx1 = FLTB($s, 3)\n\tpz = FLTB($s, 47)\n\tn = LEN($s)")
    g = emu.globals
    assert g["n"] == 50.0 and g["pz"] == 30.5                     # the position is the last column
    assert g["x1"] == pytest.approx(g["b"].rows[0], abs=1e-6)     # the first number: the x axis' x
    assert [g["d"][i] for i in range(6)] == pytest.approx([10, -20, 30.5, 15, 40, -60], abs=1e-3)
    with pytest.raises(VPlusError, match="TRANSB: its 3x3 rotation"):
        run("\tSET b = TRANSB($FLTB(2)+$FLTB(0)+$FLTB(0)+$FLTB(0)+$FLTB(1)+$FLTB(0)+$FLTB(0)+$FLTB(0)+$FLTB(1)"
            "+$FLTB(0)+$FLTB(0)+$FLTB(0))")
