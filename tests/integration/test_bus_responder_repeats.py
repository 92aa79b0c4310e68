"""Responder: a repeat of a request that is still queued must not be processed a second time.

Found by benchmarks/bench_load.py: at a request rate above what the vision node can serve, more than ``cache_size``
distinct requests wait in the Responder's queue. The Communicator re-publishes each unanswered request (20, 40,
80 ms ...), and those repeats were queued too. By the time a repeat reached the front, its original's answer had
been evicted from the cache, so the request went through the handler again. Each re-publication added a full
processing, and the node's goodput collapsed: 0 of 2000 answered in time at 500 req/s.
"""

from __future__ import annotations

import asyncio
from collections import Counter

import pytest

from aioadept.bus.communicator import Communicator
from aioadept.bus.responder import Responder
from aioadept.bus.messages import decode_event

@pytest.mark.timeout(10)
async def test_repeat_of_a_queued_request_is_not_processed_again_after_cache_eviction(bus):
    calls: list[str] = []
    a_started = asyncio.Event()
    release_a = asyncio.Event()

    async def handler(_type, rid, _attrs):
        calls.append(rid)
        if rid == "aaaaaaaa":
            a_started.set()
            await release_a.wait()
        return {"rid": rid}

    node = Responder(bus.any(), bus.any(), handler, cache_size=1)
    # Count what the node reads, per id (white box: the queue is otherwise invisible while the handler blocks).
    read: Counter[str] = Counter()
    b_repeated = asyncio.Event()
    dispatch = node._dispatch

    def counting_dispatch(payload: bytes, *args: object) -> None:
        rid = decode_event(payload)[1]
        read[rid] += 1
        dispatch(payload, *args)
        if read["bbbbbbbb"] >= 2 and read["cccccccc"] >= 1:
            b_repeated.set()

    node._dispatch = counting_dispatch  # type: ignore[method-assign]
    async with node, Communicator(node.peer_request_endpoint, node.peer_response_endpoint,
                                  timeout_s=5.0) as comm:
        await comm.request("VisionRequest", id="00000000")  # both sockets joined
        ta = asyncio.create_task(comm.request("VisionRequest", id="aaaaaaaa"))
        await a_started.wait()  # the node is busy with "a"
        tb = asyncio.create_task(comm.request("VisionRequest", id="bbbbbbbb"))
        tc = asyncio.create_task(comm.request("VisionRequest", id="cccccccc"))
        # The communicator re-publishes "b" (after 20 ms) while it waits in the node's queue behind "a".
        async with asyncio.timeout(5):
            await b_repeated.wait()
        release_a.set()
        answers = [(await t).attributes["rid"] for t in (ta, tb, tc)]

    assert answers == ["aaaaaaaa", "bbbbbbbb", "cccccccc"]
    # Each request processed once: with a cache of 1, "c" evicts "b", so a queued repeat of "b" would run again.
    assert calls == ["00000000", "aaaaaaaa", "bbbbbbbb", "cccccccc"], calls
