"""LineFramer: bytes in any split -> the same lines; the 128-character limit; resynchronisation."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.protocol import MAX_LINE, LineFramer, Oversize


def feed_all(chunks, max_line=MAX_LINE):
    framer = LineFramer(max_line=max_line)
    out = []
    for c in chunks:
        out += framer.feed(c)
    return out, framer


@pytest.mark.parametrize(
    ("stream", "expected"),
    [
        (b"", []),
        (b"abc", []),                                     # incomplete: held back
        (b"abc\r\n", [b"abc"]),
        (b"abc\n", [b"abc"]),                             # bare LF accepted
        (b"a\r\nb\r\nc\r\n", [b"a", b"b", b"c"]),
        (b"\r\n\r\n\n", []),                              # empty lines skipped
        (b"a\r\r\n", [b"a\r"]),                           # only one CR belongs to the delimiter
        (b"a\rb\r\n", [b"a\rb"]),                         # a lone CR is data (the parser rejects it)
        (b"x" * 128 + b"\r\n", [b"x" * 128]),             # exactly at the limit
        (b"x" * 129 + b"\r\nok\r\n", [Oversize(b"x" * 128), b"ok"]),
        (b"x" * 5000 + b"\nok\n", [Oversize(b"x" * 128), b"ok"]),
    ],
)
def test_framing_table(stream, expected):
    whole, _ = feed_all([stream])
    bytewise, _ = feed_all([stream[i:i + 1] for i in range(len(stream))])
    assert whole == expected
    assert bytewise == expected


def test_oversize_is_reported_before_the_delimiter_arrives_and_buffer_stays_bounded():
    framer = LineFramer(max_line=10)
    assert framer.feed(b"y" * 11) == []          # 11 bytes may still be 10 + "\r"
    assert framer.feed(b"y") == [Oversize(b"y" * 10)]
    assert framer.feed(b"z" * 1000) == []         # discarding up to the next delimiter
    assert framer.buffered == 0
    assert framer.feed(b"zzz\r\nid:ok\r\n") == [b"id:ok"]


def test_reset_forgets_partial_line():
    framer = LineFramer()
    framer.feed(b"half-a-li")
    framer.reset()
    assert framer.feed(b"ne\r\n") == [b"ne"]


def test_max_line_must_be_positive():
    with pytest.raises(ValueError, match="max_line"):
        LineFramer(max_line=0)


line_st = st.binary(min_size=0, max_size=200).map(lambda b: b.replace(b"\n", b"").replace(b"\r", b""))


@settings(max_examples=300, deadline=None)
@given(lines=st.lists(line_st, max_size=30), cuts=st.lists(st.integers(0, 10_000), max_size=40),
       crlf=st.booleans())
def test_any_split_gives_the_same_items(lines, cuts, crlf):
    stream = b"".join(line + (b"\r\n" if crlf else b"\n") for line in lines)
    points = sorted({c % (len(stream) + 1) for c in cuts})
    chunks = [stream[a:b] for a, b in zip([0, *points], [*points, len(stream)], strict=True)]
    whole, _ = feed_all([stream])
    split, framer = feed_all(chunks)
    assert split == whole
    expected = [line if len(line) <= MAX_LINE else Oversize(line[:MAX_LINE]) for line in lines if line]
    assert whole == expected
    assert framer.buffered == 0
