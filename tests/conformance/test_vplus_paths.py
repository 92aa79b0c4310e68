"""The shipped V+ server's refusal paths and its state stream, in one real ``aioadept sim --vplus`` process.

Each line a client can get wrong is refused with its own code before anything runs (the parser ``rs.online``,
the skills' argument checks), on the V+ server as on the Python sim (tests/unit/protocol covers the sim's
parser); and ``vplus/rsstate.V2``'s task serves its port beside the command port (the conformance servers run
without it). Together they run the lines of ``vplus/`` the rest of the conformance suite does not reach
(docs/vplus.md, "Line coverage of vplus/").
"""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from aioadept.ports import free_port
from aioadept.protocol import Ack, ErrorCode, Status, parse_ack
from aioadept.testing.nodes import running_node

VPLUS = Path(__file__).resolve().parents[2] / "vplus"

REFUSED = [  # (line, the code of its error ack)
    ("t0000001:", ErrorCode.MALFORMED_MESSAGE),                   # no skill
    ("t0000002::here", ErrorCode.MALFORMED_MESSAGE),              # an empty skill name
    ("t0000003:Bad!", ErrorCode.MALFORMED_MESSAGE),               # not a skill name
    ("t0000004:here::1", ErrorCode.MALFORMED_MESSAGE),            # two separators before the arguments
    ("t0000005:here:1:2", ErrorCode.MALFORMED_MESSAGE),           # a separator among the arguments
    ("t0000006:here:x", ErrorCode.ILLEGAL_VALUE),                 # not a number
    ("t0000007:here:" + ",".join(["1"] * 17), ErrorCode.WRONG_ARGUMENT_COUNT),   # over rs.maxarg (16)
    ("t0000008:stop:1", ErrorCode.WRONG_ARGUMENT_COUNT),          # a stop takes no argument: not a stop
    ("t0000009:sig", ErrorCode.WRONG_ARGUMENT_COUNT),             # no signal number
    ("t0000010:move_joints:200,0,0,0,0,0", ErrorCode.JOINT_LIMIT),          # J1 beyond its limit (170)
    ("t0000014:here:1,,2", ErrorCode.ILLEGAL_VALUE),              # an empty number
    ("t0000011:move_to_s:20000,0,0,0,0,0", ErrorCode.ILLEGAL_VALUE),       # beyond rs.maxpos (10 m)
    ("t0000012:move_rel_tool_s:0,0,0,0,0,720", ErrorCode.ILLEGAL_VALUE),   # beyond rs.maxrot (a full turn)
    ("t0000013:departs:20000", ErrorCode.ILLEGAL_VALUE),
    ("t0000015:move_to_s:5000,0,0,0,0,0", ErrorCode.SKILL_FAILED),  # 5 m away: V+'s MOVES fails
]


def stream_config(tmp_path: Path) -> Path:
    """A copy of rsconfig.V2 with the state stream on."""
    cfg = (VPLUS / "rsconfig.V2").read_text()
    assert "rs.stream = FALSE" in cfg
    (tmp_path / "rsconfig.V2").write_text(cfg.replace("rs.stream = FALSE", "rs.stream = TRUE"))
    return tmp_path / "rsconfig.V2"


async def _connect(port: int, timeout: float = 20.0) -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
    async with asyncio.timeout(timeout):
        while True:
            try:
                return await asyncio.open_connection("127.0.0.1", port)
            except OSError:
                await asyncio.sleep(0.05)


async def _ack(reader: asyncio.StreamReader) -> Ack:
    return parse_ack((await asyncio.wait_for(reader.readuntil(b"\r\n"), 15))[:-2])


@pytest.mark.timeout(90)
async def test_bad_lines_are_refused_with_their_codes_and_the_state_stream_serves_its_clients(tmp_path):
    files = [str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(stream_config(tmp_path)),
             str(VPLUS / "rsstate.V2")]
    sport = free_port()
    async with running_node("sim", "--vplus", *files, "--run", "rs.main", "--map-port", "1234=0",
                            "--map-port", "1235=0", "--map-port", f"1236={sport}", "--state-endpoint", "none",
                            log_path=tmp_path / "sim.log", ready_timeout_s=60) as node:
        reader, writer = await _connect(int(node.ready["port"]))
        writer.write(b"".join(line.encode() + b"\r\n" for line, _ in REFUSED) + b"t0000099:here\r\n")
        acks = [await _ack(reader) for _ in range(len(REFUSED) + 1)]
        got = {a.id: (a.status, a.error_code) for a in acks}
        # a malformed line's ID is still its own (rs.online reads it first)
        assert got == {**{line[:8]: (Status.ERROR, code) for line, code in REFUSED},
                       "t0000099": (Status.DONE, None)}
        here = acks[-1].pose
        # the state stream: two clients one after the other, each gets sample lines of the arm at rest there
        for _ in range(2):
            sreader, swriter = await _connect(sport)
            for _ in range(3):
                line = (await asyncio.wait_for(sreader.readuntil(b"\n"), 10)).decode()
                assert line.startswith("S1 t="), line
                assert f"p={here.x:.3f}," in line, (line, here)
            swriter.close()
        # nothing the refused lines asked for moved the arm; the status carries the error of the MOVES that failed
        writer.write(b"t0000100:here\r\nt0000101:status\r\n")
        last = await _ack(reader)
        assert last.pose == here
        status = (await asyncio.wait_for(reader.readuntil(b"\r\n"), 15)).decode()
        assert status.startswith("t0000101:done:") and ",er=0," not in status, status
        # an oversize line whose ID is still pending (a break waiting for a move) is refused as a duplicate
        writer.write(b"d0000001:set_speed:5\r\nd0000002:move_joints:-60,0,0,0,0,0\r\n")
        acks = [await _ack(reader) for _ in range(2)]
        assert [(a.id, a.status) for a in acks] == [("d0000001", Status.DONE), ("d0000002", Status.DONE)]
        writer.write(b"d0000003:break\r\nd0000003:" + b"x" * 300 + b"\r\n")
        dup = await _ack(reader)
        assert (dup.id, dup.status, dup.error_code) == ("d0000003", Status.ERROR, ErrorCode.MALFORMED_MESSAGE)
        writer.write(b"d0000004:stop\r\n")
        acks = [await _ack(reader) for _ in range(2)]
        assert sorted((a.id, a.status) for a in acks) == [("d0000003", Status.ABORTED), ("d0000004", Status.DONE)]
        writer.close()
