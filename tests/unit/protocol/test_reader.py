"""AckReader, the one reader of ack streams: the same values as LineFramer + parse_ack for any split of a stream."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.errors import RemoteProtocolError
from aioadept.geometry import Pose
from aioadept.protocol import Ack, AckReader, BadAck, LineFramer, Oversize, Status, encode_ack, parse_ack

POSES = [Pose(1, 2, 3, 4, 5, 6), Pose(480.014, -0.038, 709.975, 0.0, 179.995, 0.004)]
TAIL0 = encode_ack(Ack("0000000a", Status.DONE, 1.0, 2.0, POSES[0]))[8:]  # b":done:1.000,2.000:...\r\n"
LINES = [
    encode_ack(Ack("0000000a", Status.DONE, 1.0, 2.0, POSES[0])),
    encode_ack(Ack("0000000b", Status.DONE, 1.0, 2.0, POSES[0])),          # same pose and times text
    encode_ack(Ack("0000000c", Status.DONE, 1.5, 2.5, POSES[0])),          # same pose, new times
    encode_ack(Ack.error("0000000d", -610, "out of range", 3.0, 3.0, POSES[1])),
    encode_ack(Ack("0000000e", Status.ABORTED, 3.0, 3.0, POSES[1])),
    b"0000000f:done:x,1.000:1.000,2.000,3.000,4.000,5.000,6.000\r\n",     # bad times, cached pose
    b"0000001*:done:1.000,2.000:1.000,2.000,3.000,4.000,5.000,6.000\r\n",  # bad ID, cached pose
    b"00000010:done:inf,1.000:1.000,2.000,3.000,4.000,5.000,6.000\r\n",   # non-finite times
    b"garbage\r\n",
    b"x" * 2000 + b"\r\n",                                                 # over the ack line limit
    encode_ack(Ack("00000011", Status.DONE, 4.0, 4.0, POSES[1], ("1", "x"))),
    # The rest of LINES[0] after other heads: the same tail must not make them acks of the fast path.
    b"0000:012" + TAIL0,                                            # a colon within the first 8 bytes
    b"0000013" + TAIL0,                                             # a 7-character ID
    b"000000014" + TAIL0,                                           # a 9-character ID
    b"0000001\xe9" + TAIL0,                                        # a non-ASCII byte in the ID
]


def expected(stream: bytes) -> list:
    out = []
    for item in LineFramer(1024).feed(stream):
        if type(item) is Oversize:
            out.append(item)
            continue
        try:
            out.append(parse_ack(item))
        except RemoteProtocolError:
            out.append(("bad", item))
    return out


@settings(max_examples=400, deadline=None)
@given(picks=st.lists(st.integers(0, len(LINES) - 1), min_size=1, max_size=20), cuts=st.lists(st.integers(1, 300)))
def test_any_split_gives_what_framer_and_parse_ack_give(picks, cuts):
    stream = b"".join(LINES[i] for i in picks)
    reader, got, k = AckReader(), [], 0
    for c in cuts + [len(stream)]:
        got += reader.feed(stream[k:k + c])
        k += c
        if k >= len(stream):
            break
    got = [("bad", g.line) if type(g) is BadAck else g for g in got]
    assert got == expected(stream)
    assert all(type(g) is Ack for g in got if type(g) not in (tuple, Oversize))


def test_last_lines_are_the_received_bytes_index_for_index():
    reader = AckReader()
    values = reader.feed(LINES[0] + b"garbage\r\n")
    assert reader.last_lines == [LINES[0][:-2], b"garbage"] and type(values[1]) is BadAck


def test_acks_is_strict():
    assert AckReader().acks(LINES[0] + LINES[1]) == [parse_ack(LINES[0][:-2]), parse_ack(LINES[1][:-2])]
    with pytest.raises(RemoteProtocolError):
        AckReader().acks(LINES[0] + b"garbage\r\n")
    with pytest.raises(RemoteProtocolError) as exc:
        AckReader(max_line=16).acks(LINES[0])
    assert exc.value.code == -402


def test_a_repeated_ack_tail_takes_the_values_it_was_parsed_with():
    """The fast path for an ack that repeats the previous one's status, times and pose (all after the ID) gives the
    values of that text, also after parse() or a line with another pose came in between."""
    reader = AckReader()
    tail0 = TAIL0
    first, second = reader.feed(b"00000020" + tail0 + b"00000021" + tail0)
    assert second == Ack("00000021", Status.DONE, 1.0, 2.0, POSES[0]) and second.pose is first.pose
    reader.parse(LINES[4][:-2])  # aborted, POSES[1]: the remembered times and pose change
    (third,) = reader.feed(b"00000022" + tail0)
    assert third == Ack("00000022", Status.DONE, 1.0, 2.0, POSES[0])
    (_, _, fourth, fifth) = reader.feed(b"00000023" + tail0 + b"00000024" + tail0 + LINES[4] + b"00000025" + tail0)
    assert fourth.status is Status.ABORTED and fifth == Ack("00000025", Status.DONE, 1.0, 2.0, POSES[0])
    (bad,) = reader.feed(b"0000002*" + tail0)
    assert type(bad) is BadAck
