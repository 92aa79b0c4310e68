"""The I/O and hand skills of vplus/rsskills.V2 and the emulator's I/O and hand instructions, in virtual time.

The same wire skills run over TCP against both backends in tests/conformance/test_server_io_hand.py; here the V+
side is driven through its command ring (as tests/unit/test_vplus_sources.py does), so every refusal path and the
rs.hsig variant can be checked deterministically.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from aioadept.protocol import ErrorCode, Status, parse_ack
from aioadept.vplus import Emulator, VPlusError

ROOT = Path(__file__).resolve().parents[2]
FILES = [ROOT / "vplus" / f for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]


@pytest.fixture
def emu() -> Emulator:
    e = Emulator.load(*FILES, strict=True)
    e.call("rs.init")
    e.globals["rs.rdfast"] = False
    return e


def run(e: Emulator, data: bytes) -> list:
    """Queue the lines as the reader would (handle 7), run task 1's rs.step on each, return the acks."""
    e.call("rs.onchunk", data.decode("ascii"), 7.0, 0.0)
    g = e.globals
    while g["rs.qhead"] != g["rs.qtail"]:
        e.call("rs.step", task=1, attach=True)
    acks = []
    i = g["rs.ohead"]
    while i != g["rs.otail"]:
        acks.append(parse_ack((g["$rs.oa"][i] + g["$rs.ob"][i]).encode("ascii")))
        i = (i + 1) % int(g["rs.ocap"])
    g["rs.ohead"] = g["rs.otail"]
    return acks


def test_signal_and_sig_round_trip(emu):
    acks = run(emu, b"00000001:signal:3,2001,-8\r\n00000002:sig:3,-3,2001,8,-8,1001\r\n")
    assert [(a.id, a.status) for a in acks] == [("00000001", Status.DONE), ("00000002", Status.DONE)]
    assert acks[1].extra == ("-1,0,-1,0,-1,0",)
    io = emu.controller.io
    assert io.state(3) and io.state(2001) and not io.state(8)
    assert [(c.signal, c.on) for c in io.changes_since(0)[0]] == [(3, True), (2001, True)]


@pytest.mark.parametrize("line, code", [
    (b"00000003:signal:1001", ErrorCode.ILLEGAL_SIGNAL),      # an input
    (b"00000003:signal:3,600", ErrorCode.ILLEGAL_SIGNAL),     # no such signal: and 3 must not come on
    (b"00000003:signal:0", ErrorCode.ILLEGAL_SIGNAL),
    (b"00000003:signal:2.5", ErrorCode.ILLEGAL_VALUE),
    (b"00000003:sig:2513", ErrorCode.ILLEGAL_SIGNAL),
    (b"00000003:wait_sig:5,1", ErrorCode.ILLEGAL_SIGNAL),     # an output
    (b"00000003:wait_sig:1001,0", ErrorCode.ILLEGAL_VALUE),
    (b"00000003:wait_sig:1001,-1", ErrorCode.ILLEGAL_VALUE),
    (b"00000003:wait_sig:1001", ErrorCode.WRONG_ARGUMENT_COUNT),
])
def test_bad_numbers_get_one_error_ack_and_change_nothing(emu, line, code):
    acks = run(emu, line + b"\r\n00000004:sig:3\r\n")
    assert [(a.id, a.status, a.error_code) for a in acks] == [
        ("00000003", Status.ERROR, code), ("00000004", Status.DONE, None)]
    assert acks[1].extra == ("0",), "a refused signal changed an output"
    assert emu.controller.io.changes_since(0)[0] == []


def test_stale_arguments_of_an_earlier_command_are_not_read(emu):
    """signal takes any count: after a six-argument move, signal:5 must not also switch 'signals' 100, 500."""
    acks = run(emu, b"00000001:move_joints:3,-90,180,0,90,0\r\n00000002:signal:5\r\n00000003:sig:5,3\r\n")
    assert [a.status for a in acks] == [Status.DONE] * 3
    assert acks[2].extra == ("-1,0",)


def test_wait_sig_times_out_then_succeeds(emu):
    acks = run(emu, b"00000001:wait_sig:1002,0.2\r\n")
    assert (acks[0].status, acks[0].error_code) == (Status.ERROR, ErrorCode.SIGNAL_TIMEOUT)
    assert acks[0].t_done_s - acks[0].t_start_s >= 0.2 - 1e-3
    emu.controller.io.set_input(1002, True, emu.time_s)
    acks = run(emu, b"00000002:wait_sig:1002,0.2\r\n00000003:wait_sig:-1003,0.2\r\n")
    assert [(a.status, a.t_done_s - a.t_start_s < 0.05) for a in acks] == [(Status.DONE, True)] * 2


def test_close_hand_holds_hand_time_and_reports_closed_on_nothing(emu):
    acks = run(emu, b"00000001:close_hand\r\n00000002:wait_sig:1001,2\r\n00000003:sig:1001,1,2\r\n")
    assert [a.status for a in acks] == [Status.DONE] * 3
    assert acks[0].t_done_s - acks[0].t_start_s >= emu.globals["rs.htime"] - 1e-3
    assert acks[2].extra == ("-1,0,-1",), "closed on nothing: the closed-fully switch is on"
    io = emu.controller.io
    assert io.hand_state(emu.time_s).value == "closed"
    # with a part between the fingers the switch stays off: a pick that worked
    run(emu, b"00000004:open_hand\r\n")
    emu.run(0.5)                                   # fully open (HAND.TIME is shorter than the travel)
    assert io.hand_state(emu.time_s).value == "open"
    io.set_part_in_hand(True, emu.time_s)
    acks = run(emu, b"00000005:close_hand\r\n00000006:wait_sig:1001,1\r\n")
    assert acks[1].error_code == ErrorCode.SIGNAL_TIMEOUT
    assert io.hand.holding(emu.time_s)


def test_hand_skills_with_plain_outputs(emu):
    """rs.hsig: the skills drive rs.hopen/rs.hclose with SIGNAL (here the sim's own valves, so it moves)."""
    g = emu.globals
    g["rs.hsig"] = True
    g["rs.htime"] = 0.1
    acks = run(emu, b"00000001:close_hand\r\n00000002:sig:-1,2\r\n00000003:relax_hand\r\n00000004:sig:-1,-2\r\n")
    assert [a.status for a in acks] == [Status.DONE] * 4
    assert acks[0].t_done_s - acks[0].t_start_s >= 0.1 - 1e-3
    assert acks[1].extra == ("-1,-1",) and acks[3].extra == ("-1,-1",)


def test_hand_waits_for_rest_before_acting(emu):
    """OPENI/CLOSEI act on an arm at rest: a close_hand right behind a move acts when the motion is done."""
    acks = run(emu, b"00000001:move_joints:20,-90,180,0,90,0\r\n00000002:close_hand\r\n")
    changes = emu.controller.io.changes_since(0)[0]
    closed_at = next(c.t_s for c in changes if c.signal == 2 and c.on)
    assert closed_at >= emu.controller.trajectory.t_rest_s - 1e-6
    assert acks[1].t_done_s >= closed_at + emu.globals["rs.htime"] - 1e-3


SRC = """
.PROGRAM t()
	PARAMETER HAND.TIME = 0.2
	CLOSE
	c0 = SIG(2)
	MOVE #PPOINT(10,-90,180,0,90,0)
	c1 = SIG(2)
	BREAK
	t0 = TIMER(-3)
	OPENI
	t1 = TIMER(-3)
	SIGNAL 2001, 5, 0
	x = SIG(2001, 5, -6, 0)
	BITS 9, 4 = 5
	b = BITS(1, 16)
.END
"""


def test_emulator_instructions_on_the_shared_model():
    e = Emulator.from_source(SRC, strict=True)
    e.call("t")
    g = e.globals
    assert (g["c0"], g["c1"]) == (0.0, -1.0), "CLOSE acts as the next motion starts"
    assert g["t1"] - g["t0"] == pytest.approx(0.2, abs=2e-3), "OPENI holds the program for HAND.TIME"
    assert g["x"] == -1.0
    assert g["b"] == 1 + 16 + 256 + 1024, "outputs 1 (open valve), 5, 9 and 11"
    assert e.controller.io.hand_time_s == pytest.approx(0.2)


@pytest.mark.parametrize("line, code", [
    ("SIGNAL 1001", ErrorCode.ILLEGAL_SIGNAL), ("SIGNAL 3000", ErrorCode.ILLEGAL_SIGNAL),
    ("x = SIG(600)", ErrorCode.ILLEGAL_SIGNAL), ("PARAMETER HAND.TIME = -1", ErrorCode.ILLEGAL_VALUE)])
def test_emulator_io_errors(line, code):
    e = Emulator.from_source(f".PROGRAM t()\n\t{line}\n.END\n", strict=True)
    with pytest.raises(VPlusError) as info:
        e.call("t")
    assert info.value.code == code


def test_parameter_other_than_hand_time_is_refused_at_load():
    e = Emulator.from_source(".PROGRAM t()\n\tPARAMETER NOT.A.PARAM = 1\n.END\n")
    assert e.problems and "PARAMETER NOT.A.PARAM" in str(e.problems[0])


def test_argument_count_is_the_entrys_that_rs_step_runs(emu):
    """rs.step sets rs.xn from the command-ring entry it runs; rs.nargs reads it (sig of two signals, then one)."""
    emu.call("rs.onchunk", "00000001:sig:3,4\r\n00000002:sig:3\r\n", 7.0, 0.0)
    g = emu.globals
    acks = []
    for _ in range(2):
        emu.call("rs.step", task=1, attach=True)
        i = (g["rs.otail"] - 1) % int(g["rs.ocap"])
        acks.append(parse_ack((g["$rs.oa"][i] + g["$rs.ob"][i]).encode("ascii")))
    assert [len(a.extra[0].split(",")) for a in acks] == [2, 1], acks


def test_wait_sig_in_v_plus_wakes_on_the_hands_switch():
    src = """
.PROGRAM t()
	PARAMETER HAND.TIME = 0
	t0 = TIMER(-3)
	CLOSEI
	WAIT SIG(1001)
	t1 = TIMER(-3)
.END
"""
    e = Emulator.from_source(src, strict=True)
    e.call("t")
    travel = e.controller.io.hand.travel_s
    assert travel <= e.globals["t1"] - e.globals["t0"] <= travel + 0.017, "woken within one cycle of the switch"


def test_deferred_open_acts_as_the_following_motion_starts():
    """MOVE a; OPEN; MOVE b: with forward processing a has started already, so OPEN acts as b starts."""
    src = """
.PROGRAM t()
	MOVE #PPOINT(20,-90,180,0,90,0)
	OPEN
	x = SIG(1)
	MOVE #PPOINT(0,-90,180,0,90,0)
	t1 = TIMER(-3)
	BREAK
.END
"""
    e = Emulator.from_source(src, strict=True)
    e.call("t")
    assert e.globals["x"] == 0.0, "OPEN acted before the next motion"
    opened = next(c.t_s for c in e.controller.io.changes_since(0)[0] if c.signal == 1 and c.on)
    # the second MOVE returns as its motion starts (forward processing): that is when OPEN acted
    assert opened > 0.0 and opened == pytest.approx(e.globals["t1"], abs=2e-3)
    assert e.controller.io.hand_state(e.time_s).value == "open"
