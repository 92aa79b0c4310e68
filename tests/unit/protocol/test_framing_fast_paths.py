"""The framer's fast paths (one whole line; whole CRLF lines) give what byte-by-byte feeding gives."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from aioadept.protocol import LineFramer

chunks = st.lists(st.one_of(st.sampled_from([b"\r\n", b"\n", b"\r", b"a", b"abcdefgh:done:1.0"]),
                            st.binary(max_size=12)), max_size=8).map(b"".join)


@given(data=chunks, max_line=st.integers(1, 20))
def test_one_feed_equals_byte_by_byte(data, max_line):
    whole = LineFramer(max_line).feed(data)
    framer = LineFramer(max_line)
    bytewise = [item for k in range(len(data)) for item in framer.feed(data[k:k + 1])]
    assert whole == bytewise


def test_single_line_fast_path_keeps_inner_cr_and_limits():
    assert LineFramer(8).feed(b"a\rb\r\r\n") == [b"a\rb\r"]
    assert LineFramer(3).feed(b"abcd\r\n")[0].head == b"abc"  # Oversize, not a line
    assert LineFramer(8).feed(b"\r\n") == []
