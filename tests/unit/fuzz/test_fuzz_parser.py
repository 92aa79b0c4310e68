"""Fuzz properties of the server-side parser (parse_command): anything in, a message or our protocol error out.

For every input line the parser returns a CommandMessage that re-encodes to the same text, or raises
RemoteProtocolError with a code from the table and, when it names an ID, an ID that really heads the line. The
ID rule is the one servers rely on to route error acks (docs/protocol.md, section 3.2).
"""

from __future__ import annotations

import math

from hypothesis import example, given, settings
from hypothesis import strategies as st

from aioadept.errors import RemoteProtocolError
from aioadept.protocol import (
    MAX_LINE,
    CommandMessage,
    ErrorCode,
    SkillCall,
    encode_command,
    format_arg,
    parse_command,
    recover_id,
)

from fuzz_strategies import lines, near_lines

KNOWN_CODES = {int(c) for c in ErrorCode}


def check_one(line: bytes) -> CommandMessage | RemoteProtocolError:
    try:
        msg = parse_command(line)
    except RemoteProtocolError as exc:  # anything else propagates and fails the test
        assert exc.code in KNOWN_CODES
        assert exc.line == line
        if exc.id is not None:
            assert len(exc.id) == 8 and exc.id.isascii() and exc.id.isalnum()
            assert line.startswith(exc.id.encode())
        if len(line) > MAX_LINE:
            assert exc.code == ErrorCode.LINE_TOO_LONG
        return exc
    assert len(line) <= MAX_LINE
    assert len(msg.id) == 8 and msg.id.isalnum() and recover_id(line) == msg.id
    assert all(type(a) in (int, float) and math.isfinite(a) for a in msg.args)
    return msg


@settings(max_examples=150, deadline=None)
@given(line=lines)
@example(b"nee861124:break")                       # the paper's 9-character ID
@example(b"eae86869:move_to:-80.000,-481.000,112.500,180.000,90.000,180.000")
@example(b"abcdefgh")                               # an ID and nothing else
@example(b"abcdefgh:" + b"9" * 130)                 # oversize with a recoverable ID
@example(b"abcdefgh:set_speed:" + b"9" * 100)       # a huge integer within 128 characters
@example(b"\xffbcdefgh:here")
def test_any_line_gives_a_message_or_our_protocol_error(line):
    result = check_one(line)
    if isinstance(result, CommandMessage):
        # A line that parses is exactly ID:SKILL[:ARGS] of what was parsed (modulo number spelling).
        head = f"{result.id}:{result.skill}".encode()
        assert line == head or line.startswith(head + b":")


@settings(max_examples=70, deadline=None)
@given(line=near_lines(), pos=st.integers(0, 200), byte=st.integers(0, 255))
def test_single_byte_corruption_of_nearly_valid_lines(line, pos, byte):
    b = bytearray(line)
    if b:
        b[pos % len(b)] = byte
    check_one(bytes(b))


reals = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e5, max_value=1e5)


@settings(max_examples=70, deadline=None)
@given(mid=st.text("0123456789abcdefABCXYZ", min_size=8, max_size=8).filter(lambda m: m != "00000000"),
       skill=st.from_regex(r"[a-z][a-z0-9._]{0,14}", fullmatch=True),
       args=st.lists(st.one_of(reals, st.integers(-10_000, 10_000)), max_size=6))
def test_what_the_client_encodes_the_server_parses(mid, skill, args):
    try:
        call = SkillCall(skill, tuple(args))
    except ValueError:  # over 128 characters: the client refuses it before it reaches a wire
        return
    wire = encode_command(mid, call)
    assert wire.endswith(b"\r\n")
    msg = parse_command(wire[:-2])
    assert (msg.id, msg.skill, len(msg.args)) == (mid, skill, len(args))
    for sent, got in zip(args, msg.args, strict=True):
        # The wire carries %.3f (reals) or %d (ints): the parsed value is that text's value.
        assert got == type(got)(format_arg(sent)) and abs(got - sent) <= 0.0005 + 1e-9 * abs(sent)
