"""Fuzz properties of LineFramer: arbitrary bytes in arbitrary splits against a two-line reference model.

The model is the framing rule of docs/protocol.md written as plainly as possible: cut at LF, drop one CR before
it, skip empty lines, report a line over the limit as Oversize(first max_line bytes). The framer must agree with
it for any byte stream and any split, keep its buffer bounded, and never raise.
"""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.protocol import LineFramer, Oversize


def reference(stream: bytes, max_line: int) -> list[bytes | Oversize]:
    *complete, tail = stream.split(b"\n")
    out: list[bytes | Oversize] = []
    for seg in complete:
        line = seg[:-1] if seg.endswith(b"\r") else seg
        if line:
            out.append(Oversize(line[:max_line]) if len(line) > max_line else line)
    # A partial line that can no longer fit (even if its last byte is the CR of a CRLF) is reported early.
    if len(tail) > max_line + 1:
        out.append(Oversize(tail[:max_line]))
    return out


# Bytes rich in delimiters so that lines are short and the limit is hit often with small max_line.
streams = st.one_of(
    st.binary(max_size=600),
    st.lists(st.sampled_from([b"\r", b"\n", b"\r\n", b"a", b"0", b":", b"xyz", b"\xff"]), max_size=200).map(b"".join),
)


@settings(max_examples=120, deadline=None)
@given(stream=streams, cuts=st.lists(st.integers(0, 600), max_size=30), max_line=st.integers(1, 12))
def test_any_stream_any_split_matches_the_reference(stream, cuts, max_line):
    framer = LineFramer(max_line)
    out: list[bytes | Oversize] = []
    prev = 0
    for c in sorted(set(min(c, len(stream)) for c in cuts)) + [len(stream)]:
        out += framer.feed(stream[prev:c])
        prev = c
        # Bounded memory: never more than one line's worth held, however the stream misbehaves.
        assert framer.buffered <= max_line + 1
    assert out == reference(stream, max_line)
    for item in out:
        if isinstance(item, Oversize):
            assert len(item.head) == max_line
        else:
            assert item and b"\n" not in item and len(item) <= max_line


@settings(max_examples=50, deadline=None)
@given(stream=streams, max_line=st.integers(1, 12))
def test_byte_at_a_time_equals_one_feed(stream, max_line):
    one = LineFramer(max_line).feed(stream)
    framer = LineFramer(max_line)
    bytewise: list[bytes | Oversize] = []
    for i in range(len(stream)):
        bytewise += framer.feed(stream[i:i + 1])
    assert bytewise == one


@settings(max_examples=40, deadline=None)
@given(junk=st.binary(max_size=400), max_line=st.integers(1, 12))
def test_stream_resynchronises_after_any_junk(junk, max_line):
    # Whatever came before, the line after the next LF is framed intact.
    framer = LineFramer(max_line)
    framer.feed(junk)
    want = b"ok" if max_line >= 2 else Oversize(b"o")
    assert framer.feed(b"\nok\r\n")[-1] == want
    framer.reset()
    assert framer.buffered == 0 and framer.feed(b"z\n") == [b"z"]
