"""Command and ack encoders/parsers: table tests of both directions, every extension, and properties."""

from __future__ import annotations

import math

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from aioadept.errors import LocalProtocolError, ProtocolError, RemoteProtocolError
from aioadept.geometry import Pose
from aioadept.protocol import (
    NO_ID,
    Ack,
    CommandMessage,
    ErrorCode,
    IdAllocator,
    LineFramer,
    SkillCall,
    Status,
    describe,
    encode_ack,
    encode_command,
    parse_ack,
    parse_command,
    recover_id,
    sanitize_text,
)

PAPER_CHAIN = b"eae86869:move_to:-80.000,-481.000,112.500,180.000,90.000,180.000\r\nnee861124:break\r\n"
PAPER_ACK = b"eae86869:done:2492.516,2492.539:480.014,-0.038,709.975,0.000,179.995,0.004\r\n"
PAPER_POSE = Pose(480.014, -0.038, 709.975, 0.0, 179.995, 0.004)
P0 = Pose(1.0, -2.0, 3.5, 0.0, 180.0, -0.5)


# ---------------------------------------------------------------------------------------- client -> server
COMMANDS = [
    ("eae86869", SkillCall("move_to", (-80.0, -481.0, 112.5, 180.0, 90.0, 180.0)),
     b"eae86869:move_to:-80.000,-481.000,112.500,180.000,90.000,180.000\r\n"),
    ("ee861124", SkillCall("break"), b"ee861124:break\r\n"),
    ("0000000a", SkillCall("set_speed", (20,)), b"0000000a:set_speed:20\r\n"),
    ("0000000b", SkillCall("enable_air"), b"0000000b:enable_air\r\n"),
    ("0000000c", SkillCall("disable_air"), b"0000000c:disable_air\r\n"),
    ("0000000d", SkillCall("move_rel_tool", (0.0, 0.0, 2.5, 0.0, 0.0, 0.0)),
     b"0000000d:move_rel_tool:0.000,0.000,2.500,0.000,0.000,0.000\r\n"),
    ("0000000e", SkillCall("move_joints", (0.0, -90.0, 180.0, 0.0, 90.0, 0.0)),
     b"0000000e:move_joints:0.000,-90.000,180.000,0.000,90.000,0.000\r\n"),
    ("0000000f", SkillCall("stop"), b"0000000f:stop\r\n"),        # extensions
    ("00000010", SkillCall("here"), b"00000010:here\r\n"),
    ("00000011", SkillCall("hello"), b"00000011:hello\r\n"),
    ("00000012", SkillCall("my.skill_2", (1, -0.0004)), b"00000012:my.skill_2:1,-0.000\r\n"),
]


@pytest.mark.parametrize(("mid", "call", "wire"), COMMANDS)
def test_command_table_both_directions(mid, call, wire):
    assert encode_command(mid, call) == wire
    msg = parse_command(wire[:-2])
    assert msg == CommandMessage(mid, call.skill, tuple(float("%.3f" % a) if isinstance(a, float) else a
                                                       for a in call.args))
    assert [type(a) for a in msg.args] == [type(a) for a in call.args]  # set_speed stays an int


def test_paper_chain_first_message_parses_and_second_nine_char_id_is_rejected_without_id():
    lines = LineFramer().feed(PAPER_CHAIN)
    assert len(lines) == 2
    first = parse_command(lines[0])
    assert first == CommandMessage("eae86869", "move_to", (-80.0, -481.0, 112.5, 180.0, 90.0, 180.0))
    with pytest.raises(RemoteProtocolError) as info:
        parse_command(lines[1])  # b"nee861124:break": 9 characters before ':' (a typo in the paper)
    assert info.value.code == ErrorCode.MALFORMED_MESSAGE
    assert info.value.id is None  # so a server answers with 00000000
    assert info.value.line == b"nee861124:break"


@pytest.mark.parametrize(
    ("line", "code", "mid"),
    [
        (b"abc:break", ErrorCode.MALFORMED_MESSAGE, None),                  # short ID
        (b"eae86869", ErrorCode.MALFORMED_MESSAGE, "eae86869"),             # no skill
        (b"eae86869:", ErrorCode.MALFORMED_MESSAGE, "eae86869"),            # empty skill
        (b"eae86869:Move_To:1", ErrorCode.MALFORMED_MESSAGE, "eae86869"),   # uppercase skill
        (b"eae86869:abcdefghijklmnop", ErrorCode.MALFORMED_MESSAGE, "eae86869"),  # 16-char skill
        (b"eae86869:move_to:1,2:3", ErrorCode.MALFORMED_MESSAGE, "eae86869"),  # 4 fields
        (b"eae86869:move_to:1,x,3", ErrorCode.ILLEGAL_VALUE, "eae86869"),
        (b"eae86869:move_to:1,,3", ErrorCode.ILLEGAL_VALUE, "eae86869"),
        (b"eae86869:move_to:1e5", ErrorCode.ILLEGAL_VALUE, "eae86869"),    # no exponents
        (b"eae86869:move_to:nan", ErrorCode.ILLEGAL_VALUE, "eae86869"),
        (b"eae86869:move_to:", ErrorCode.ILLEGAL_VALUE, "eae86869"),
        (b"eae86869:br\xffak", ErrorCode.MALFORMED_MESSAGE, "eae86869"),   # non-ASCII
        (b"eae86869:set_speed:" + b"1" * 120, ErrorCode.LINE_TOO_LONG, "eae86869"),
    ],
)
def test_bad_command_lines(line, code, mid):
    with pytest.raises(RemoteProtocolError) as info:
        parse_command(line)
    assert info.value.code == code
    assert info.value.id == mid


def test_command_number_forms_accepted_by_server():
    msg = parse_command(b"eae86869:move_to:+1,-2.,.5,-0.25,7,0")
    assert msg.args == (1, -2.0, 0.5, -0.25, 7, 0)
    assert [type(a) for a in msg.args] == [int, float, float, float, int, int]


@pytest.mark.parametrize("tok", [b" 7", b"7 ", b"\t7", b"7\x00", b"1e3", b"1E3", b"1_0", b"inf", b"-inf", b"nan",
                                 b"0x1f", b"--1", b"1.2.3", b"", b"\xb9", b"1" * 25, b"0." + b"0" * 30 + b"1"])
def test_command_numbers_outside_the_grammar_are_refused(tok):
    # The grammar is the original client's %d / %.3f text: no spaces, exponents, '_', inf or nan (all of which
    # Python's float() accepts), no control characters, at most MAX_NUMBER_CHARS characters.
    with pytest.raises(RemoteProtocolError) as info:
        parse_command(b"eae86869:set_speed:" + tok)
    assert info.value.code in (ErrorCode.ILLEGAL_VALUE, ErrorCode.MALFORMED_MESSAGE)
    assert info.value.id == "eae86869"


def test_the_reserved_id_is_refused():
    with pytest.raises(RemoteProtocolError) as info:
        parse_command(b"00000000:here")
    assert info.value.code == ErrorCode.MALFORMED_MESSAGE and "reserved" in info.value.message


def test_encode_command_rejects_bad_id():
    with pytest.raises(LocalProtocolError):
        encode_command("abc", SkillCall("break"))
    with pytest.raises(LocalProtocolError):
        encode_command("eae8686:", SkillCall("break"))


# ---------------------------------------------------------------------------------------- server -> client
ACKS = [
    (Ack("eae86869", Status.DONE, 2492.516, 2492.539, PAPER_POSE), PAPER_ACK),
    (Ack("0000000a", Status.ERROR, 1.0, 1.0, P0, ("-610", "location out of range")),
     b"0000000a:error:1.000,1.000:1.000,-2.000,3.500,0.000,180.000,-0.500:-610:location out of range\r\n"),
    (Ack("0000000b", Status.ABORTED, 2.0, 2.25, P0),
     b"0000000b:aborted:2.000,2.250:1.000,-2.000,3.500,0.000,180.000,-0.500\r\n"),
    (Ack("0000000c", Status.DONE, 0.5, 0.5, P0, ("1", "aioadept-sim 0.1.0")),     # hello
     b"0000000c:done:0.500,0.500:1.000,-2.000,3.500,0.000,180.000,-0.500:1:aioadept-sim 0.1.0\r\n"),
    (Ack(NO_ID, Status.ERROR, 0.0, 0.0, P0, ("-401", "bad message ID")),
     b"00000000:error:0.000,0.000:1.000,-2.000,3.500,0.000,180.000,-0.500:-401:bad message ID\r\n"),
]


@pytest.mark.parametrize(("ack", "wire"), ACKS)
def test_ack_table_both_directions(ack, wire):
    assert encode_ack(ack) == wire
    assert parse_ack(wire[:-2]) == ack


def test_paper_ack_verbatim():
    ack = parse_ack(PAPER_ACK.rstrip(b"\r\n"))
    assert (ack.id, ack.status, ack.t_start_s, ack.t_done_s) == ("eae86869", Status.DONE, 2492.516, 2492.539)
    assert ack.pose == PAPER_POSE and ack.ok and ack.extra == ()
    assert ack.error_code is None and ack.error_message is None


def test_error_ack_fields_and_constructor():
    ack = Ack.error("0000000a", ErrorCode.UNKNOWN_SKILL, None, 1.0, 2.0, P0)
    assert ack.extra == ("-406", "undefined skill")
    assert (ack.error_code, ack.error_message) == (-406, "undefined skill")
    assert Ack.error(None, -9999, None, 0, 0, P0).extra == ("-9999", "")   # code not in the table
    assert Ack.error(None, -300, "bad: thing\r\nhappened", 0, 0, P0).extra[1] == "bad; thing  happened"
    assert describe(-610) == "OUT_OF_REACH" and describe(-1) == "code -1"
    assert sanitize_text("é" * 100) == "?" * 80


def test_original_client_view_of_extended_acks_is_unchanged():
    # The original client splits on ':' and reads the leading fields; trailing fields never shift them.
    for ack, wire in ACKS:
        fields = wire.rstrip(b"\r\n").split(b":")
        assert fields[0].decode() == ack.id and fields[1].decode() == ack.status.value
        assert len(fields[3].split(b",")) == 6


@pytest.mark.parametrize(
    "line",
    [
        b"eae86869:done:1.0,2.0",                                  # too few fields
        b"eae86869:finished:1.0,2.0:1,2,3,4,5,6",                  # unknown status
        b"eae8686:done:1.0,2.0:1,2,3,4,5,6",                       # short ID
        b"eae86869:done:1.0:1,2,3,4,5,6",                          # one time
        b"eae86869:done:1.0,2.0:1,2,3,4,5",                        # five pose numbers
        b"eae86869:done:1.0,x:1,2,3,4,5,6",
        b"eae86869:done:1.0,2.0:1,2,3,4,5,nan",
        b"eae86869:done:1.0,2.0:1,2,3,4,5,inf",
        b"eae86869:error:1.0,2.0:1,2,3,4,5,6",                     # error without code
        b"eae86869:error:1.0,2.0:1,2,3,4,5,6:oops:text",
        b"eae86869:d\xc3\xb6ne:1.0,2.0:1,2,3,4,5,6",
    ],
)
def test_bad_ack_lines(line):
    with pytest.raises(RemoteProtocolError) as info:
        parse_ack(line)
    assert info.value.code == ErrorCode.MALFORMED_MESSAGE


@pytest.mark.parametrize(
    "ack",
    [
        Ack("short", Status.DONE, 0, 0, P0),
        Ack("0000000a", Status.DONE, math.nan, 0, P0),
        Ack("0000000a", Status.DONE, 0, 0, Pose(math.inf)),
        Ack("0000000a", Status.DONE, 0, 0, P0, ("a:b",)),
        Ack("0000000a", Status.DONE, 0, 0, P0, ("line\r\n",)),
        Ack("0000000a", Status.DONE, 0, 0, P0, ("é",)),
        Ack("0000000a", Status.ERROR, 0, 0, P0, ()),
        Ack("0000000a", Status.ERROR, 0, 0, P0, ("text",)),
        Ack("0000000a", "finished", 0, 0, P0),  # type: ignore[arg-type]
    ],
)
def test_encode_ack_rejects_what_cannot_be_parsed_back(ack):
    with pytest.raises(LocalProtocolError):
        encode_ack(ack)


def test_recover_id():
    assert recover_id(b"eae86869:whatever \xff") == "eae86869"
    assert recover_id(b"nee861124:break") is None
    assert recover_id(b"eae8686\xff:x") is None
    assert recover_id(b"short") is None


def test_id_allocator_is_8_hex_unique_skips_zero_and_wraps():
    ids = IdAllocator(0xFFFFFFFE)
    got = [ids.next() for _ in range(4)]
    assert got == ["fffffffe", "ffffffff", "00000001", "00000002"]
    ids = IdAllocator(12345)
    many = [ids.next() for _ in range(10_000)]
    assert len(set(many)) == 10_000 and all(len(i) == 8 and int(i, 16) for i in many)


# ---------------------------------------------------------------------------------------- properties
finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)
skill_st = st.from_regex(r"[a-z][a-z0-9._]{0,14}", fullmatch=True)
id_st = st.from_regex(r"[0-9a-f]{8}", fullmatch=True)
cmd_id_st = id_st.filter(lambda m: m != "00000000")  # the reserved ID: a server refuses commands carrying it
arg_st = st.one_of(st.integers(-10**6, 10**6), finite)
call_st = st.builds(lambda s, a: SkillCall(s, tuple(a)), skill_st, st.lists(arg_st, max_size=6))
field_st = st.text(st.characters(min_codepoint=32, max_codepoint=126, blacklist_characters=":"), max_size=20)
ack_st = st.builds(
    lambda mid, status, t, pose, extra: Ack(mid, status, t[0], t[1], Pose(*pose),
                                           (str(-abs(extra[0])), *extra[1]) if status is Status.ERROR
                                           else tuple(extra[1])),
    id_st, st.sampled_from(Status), st.tuples(finite, finite), st.tuples(*[finite] * 6),
    st.tuples(st.integers(0, 2000), st.lists(field_st, max_size=3)),
)


def _r3(v: float) -> float:
    return float("%.3f" % v)


@settings(max_examples=300, deadline=None)
@given(mid=cmd_id_st, call=call_st)
def test_command_round_trip(mid, call):
    msg = parse_command(encode_command(mid, call)[:-2])
    assert msg.id == mid and msg.skill == call.skill
    assert msg.args == tuple(_r3(a) if isinstance(a, float) else a for a in call.args)


@settings(max_examples=300, deadline=None)
@given(ack=ack_st)
def test_ack_round_trip(ack):
    back = parse_ack(encode_ack(ack)[:-2])
    assert back.id == ack.id and back.status is ack.status and back.extra == ack.extra
    assert (back.t_start_s, back.t_done_s) == (_r3(ack.t_start_s), _r3(ack.t_done_s))
    assert back.pose.as_tuple() == tuple(map(_r3, ack.pose.as_tuple()))
    assert encode_ack(back) == encode_ack(ack)  # a second trip is exact


@settings(max_examples=100, deadline=None)
@given(pairs=st.lists(st.tuples(cmd_id_st, call_st), min_size=1, max_size=20),
       cuts=st.lists(st.integers(0, 100_000), max_size=30))
def test_any_split_of_a_valid_command_stream_gives_identical_messages(pairs, cuts):
    stream = b"".join(encode_command(mid, call) for mid, call in pairs)
    points = sorted({c % (len(stream) + 1) for c in cuts})
    framer = LineFramer()
    got = []
    for a, b in zip([0, *points], [*points, len(stream)], strict=True):
        got += [parse_command(line) for line in framer.feed(stream[a:b])]
    assert got == [parse_command(encode_command(mid, call)[:-2]) for mid, call in pairs]


@settings(max_examples=100, deadline=None)
@given(acks=st.lists(ack_st, min_size=1, max_size=20), cuts=st.lists(st.integers(0, 100_000), max_size=30))
def test_any_split_of_a_valid_ack_stream_gives_identical_acks(acks, cuts):
    stream = b"".join(map(encode_ack, acks))
    points = sorted({c % (len(stream) + 1) for c in cuts})
    framer = LineFramer(max_line=1024)
    got = []
    for a, b in zip([0, *points], [*points, len(stream)], strict=True):
        got += [parse_ack(line) for line in framer.feed(stream[a:b])]
    assert got == [parse_ack(encode_ack(a)[:-2]) for a in acks]


garbage_st = st.one_of(
    st.binary(max_size=300),
    st.text(st.sampled_from("0123456789abcdef:,.-+e \r\nnaifdoe_rt"), max_size=200).map(str.encode),
)


@settings(max_examples=500, deadline=None)
@given(data=garbage_st)
def test_garbage_raises_only_protocol_errors(data):
    framer = LineFramer()
    for item in framer.feed(data) + framer.feed(b"\n"):
        assume(isinstance(item, bytes))
        for parse in (parse_command, parse_ack):
            try:
                parse(item)
            except ProtocolError:
                pass
    for parse in (parse_command, parse_ack):
        try:
            parse(data)
        except ProtocolError:
            pass


@settings(max_examples=150, deadline=None)
@given(items=st.lists(st.one_of(ack_st.map(lambda a: encode_ack(a)[:-2]), garbage_st,
                                st.sampled_from([b"0000000a:done:1.0,2.0:1,2,3,4,5,6",
                                                 b"0000000b:done:1.5,x:1,2,3,4,5,6",
                                                 b"000\xff000b:done:1.5,2:1,2,3,4,5,6",
                                                 b"0000000c:done:nan,2:1,2,3,4,5,6"])), max_size=20))
def test_ack_reader_parse_gives_exactly_what_parse_ack_gives(items):
    from aioadept.protocol import AckReader

    parser = AckReader()
    for line in items:
        try:
            want = parse_ack(line)
        except RemoteProtocolError as exc:
            with pytest.raises(RemoteProtocolError) as info:
                parser.parse(line)
            assert (info.value.code, info.value.id) == (exc.code, exc.id)
        else:
            assert parser.parse(line) == want
