"""IdAllocator.take gives the same IDs as as many calls of next(), across runs of 256 and the wrap at 2**32."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from aioadept.protocol import IdAllocator

starts = st.one_of(st.integers(0, 2**32 - 1), st.sampled_from([0, 1, 0xFF, 0x100, 0xFFFFFF00, 0xFFFFFFFF]),
                   st.integers(2**32 - 700, 2**32 - 1))


@given(start=starts, counts=st.lists(st.integers(0, 600), min_size=1, max_size=4))
def test_take_is_next_repeated(start, counts):
    a, b = IdAllocator(start), IdAllocator(start)
    for count in counts:
        assert a.take(count) == [b.next() for _ in range(count)]
    assert a.next() == b.next()
