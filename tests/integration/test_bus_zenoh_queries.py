"""Vision requests as Zenoh queries: a Responder on Zenoh is a queryable, so any Zenoh querier
(another language, ``z_get``) can ask it with the Protobuf event and get the answer as the reply; a
``Communicator(queries=True)`` sends its requests as queries, to a Responder or to a queryable written without
aioadept. The pairing contract is the one both transports share (test_bus_communicator.py, ...): what is tested here
is what queries add: the answer goes to the query (not published), a repeat's query gets it, and a query that will
never be answered is finalized at once instead of hanging until Zenoh's timeout.

Real Zenoh sessions: this process is a loopback router (tests/integration/bustransports.py)."""

from __future__ import annotations

import asyncio
import importlib.util
import itertools
import os

import pytest

from aioadept.bus import Communicator, Responder, Subscriber, Publisher
from aioadept.bus.messages import decode_event, encode_event

from bustransports import start_zenoh_router

pytestmark = pytest.mark.skipif(importlib.util.find_spec("zenoh") is None,
                                reason="the [zenoh] extra (eclipse-zenoh) is not installed")

_keys = itertools.count()


@pytest.fixture
def keys() -> tuple[str, str]:
    start_zenoh_router()
    base = f"zenoh:aioadept/qtest/{os.urandom(3).hex()}/{next(_keys)}"
    return f"{base}/request", f"{base}/response"


def _key(endpoint: str) -> str:
    return endpoint.removeprefix("zenoh:")


async def _ask(endpoint: str, payload: bytes) -> list[bytes]:
    """A plain zenoh-python query, as any Zenoh application would send it; the replies' payloads once the query is
    finalized (its timeout is far beyond each test's, so a query left hanging fails the test)."""
    from aioadept.bus import zenoh as zb

    replies = zb.session().get(_key(endpoint), payload=payload, timeout=120.0)
    return await asyncio.to_thread(lambda: [r.ok.payload.to_bytes() for r in replies if r.ok is not None])


class Held:
    """A Responder handler that holds every request until ``release`` is set; ``started``: one has arrived."""

    def __init__(self, answer: dict) -> None:
        self.answer = answer
        self.started = asyncio.Event()
        self.release = asyncio.Event()

    async def __call__(self, event_type: str, rid: str | None, attrs: dict) -> dict:
        self.started.set()
        await self.release.wait()
        return self.answer


@pytest.mark.timeout(30)
async def test_any_zenoh_querier_asks_a_responder_with_the_protobuf_event_and_gets_the_answer_as_the_reply(keys):
    req, resp = keys
    async with Responder(req, resp, lambda t, rid, a: {"seen": a["k"] * 2}) as node, \
            Subscriber(resp) as published:
        replies = await _ask(req, encode_event("VisionRequest", "a1b2c3d4", {"k": 21}))
        assert [decode_event(r) for r in replies] == [("VisionResponse", "a1b2c3d4", {"seen": 42})]
        # Asked again with the same id: the answer comes from the cache, the handler is not run twice.
        again = await _ask(req, encode_event("VisionRequest", "a1b2c3d4", {"k": 99}))
        assert again == replies
        assert (node.handled, node.cache_hits) == (1, 1)
        # The answers went to the asker only: nothing was published on the response key.
        with pytest.raises(TimeoutError):
            await asyncio.wait_for(published.recv(), 0.3)


@pytest.mark.timeout(30)
async def test_a_communicator_with_queries_is_answered_by_reply_and_one_without_by_publication(keys):
    req, resp = keys
    async with Responder(req, resp, lambda t, rid, a: {"n": a["n"]}), Subscriber(resp) as published:
        async with Communicator(req, resp, queries=True, timeout_s=10) as comm:
            for n in range(5):
                assert (await comm.request("VisionRequest", {"n": n})).attributes == {"n": n}
        with pytest.raises(TimeoutError):
            await asyncio.wait_for(published.recv(), 0.3)
        async with Communicator(req, resp, timeout_s=10) as comm:
            r = await comm.request("VisionRequest", {"n": 7})
        assert r.attributes == {"n": 7}
        _, payload = await asyncio.wait_for(published.recv(), 5)  # this answer was published
        assert decode_event(payload) == ("VisionResponse", r.id, {"n": 7})


@pytest.mark.timeout(30)
async def test_a_communicator_with_queries_asks_a_queryable_written_without_aioadept_and_re_sends_until_answered(keys):
    import zenoh

    from aioadept.bus import zenoh as zb

    req, resp = keys
    seen: list[str] = []

    def answer(query) -> None:  # a node in plain zenoh-python: lets the first copy of each request go unanswered
        with query:
            event_type, rid, attrs = decode_event(query.payload.to_bytes())
            seen.append(rid)
            if seen.count(rid) > 1:
                query.reply(query.key_expr, encode_event("VisionResponse", rid, {"twice": attrs["x"] * 2}))

    queryable = zb.session().declare_queryable(_key(req), zenoh.handlers.Callback(answer))
    try:
        async with Communicator(req, resp, queries=True, timeout_s=10, republish_interval_s=0.05) as comm:
            r = await comm.request("VisionRequest", {"x": 1.5})
        assert r.attributes == {"twice": 3.0}
        assert seen == [r.id, r.id]
        assert comm.republished >= 1
    finally:
        queryable.undeclare()


@pytest.mark.timeout(20)
async def test_a_query_the_responder_will_not_answer_is_finalized_at_once(keys):
    req, resp = keys
    async with Responder(req, resp, lambda t, rid, a: {}, request_types={"VisionRequest"}) as node:
        assert await _ask(req, encode_event("Shutdown", "00000001", {})) == []  # not a type it serves
        assert await _ask(req, b"\xffnot protobuf") == []
        stale = {"t_deadline": 1.0}  # its requester gave up long ago
        assert await _ask(req, encode_event("VisionRequest", "00000002", stale)) == []
        assert (node.handled, node.ignored, node.expired) == (0, 1, 1)


@pytest.mark.timeout(30)
async def test_a_repeat_while_in_process_gets_the_answer_and_the_older_copy_is_let_go(keys):
    req, resp = keys
    slow = Held({"done": 1})
    payload = encode_event("VisionRequest", "0badcafe", {})
    async with Responder(req, resp, slow) as node:
        first = asyncio.ensure_future(_ask(req, payload))
        await asyncio.wait_for(slow.started.wait(), 10)
        second = asyncio.ensure_future(_ask(req, payload))
        # The older copy is let go as soon as the repeat arrives: its asker learns that no reply follows.
        assert await asyncio.wait_for(first, 10) == []
        slow.release.set()
        assert [decode_event(r) for r in await asyncio.wait_for(second, 10)] == [
            ("VisionResponse", "0badcafe", {"done": 1})]
        assert node.handled == 1


@pytest.mark.timeout(30)
async def test_a_query_pushed_off_a_full_queue_is_answered_dropped_and_closing_lets_the_waiting_ones_go(keys):
    req, resp = keys
    slow = Held({})
    async with Responder(req, resp, slow, max_queue=1) as node:
        busy = asyncio.ensure_future(_ask(req, encode_event("VisionRequest", "000000a1", {})))
        await asyncio.wait_for(slow.started.wait(), 10)
        queued = asyncio.ensure_future(_ask(req, encode_event("VisionRequest", "000000a2", {})))
        while not node._queue:  # the second one waits behind the first
            await asyncio.sleep(0.01)
        newest = asyncio.ensure_future(_ask(req, encode_event("VisionRequest", "000000a3", {})))
        (dropped,) = await asyncio.wait_for(queued, 10)
        event_type, rid, attrs = decode_event(dropped)
        assert (event_type, rid) == ("VisionResponse", "000000a2")
        assert attrs["error"].startswith("dropped:")
    # Closed with one query in process and one queued: both askers are told at once that nothing follows.
    assert await asyncio.wait_for(busy, 10) == []
    assert await asyncio.wait_for(newest, 10) == []
    assert node.dropped == 1


@pytest.mark.timeout(30)
async def test_a_hand_written_node_reads_queries_with_a_subscriber_and_answers_by_publishing(keys):
    req, resp = keys
    async with Subscriber(req, queries=True) as requests, Publisher(resp) as answers:
        async def node() -> None:
            while True:
                _, payload = await requests.recv()
                _, rid, attrs = decode_event(payload)
                answers.send_nowait(encode_event("VisionResponse", rid, {"echo": attrs["v"]}))

        task = asyncio.create_task(node())
        try:
            async with Communicator(req, resp, queries=True, timeout_s=10) as comm:
                assert (await comm.request("VisionRequest", {"v": "hi"})).attributes == {"echo": "hi"}
        finally:
            task.cancel()


@pytest.mark.timeout(30)
@pytest.mark.parametrize("queries", [False, True], ids=["publications", "queries"])
async def test_a_timeout_says_when_nothing_on_the_bus_takes_the_requests(keys, queries):
    # The usual mistake in a cell spread over machines (a node in another cell, or on another router) gives a
    # timeout that says so; a node that is there but slow does not.
    from aioadept.errors import RequestTimeout

    req, resp = keys
    async with Communicator(req, resp, queries=queries, timeout_s=0.5) as comm:
        with pytest.raises(RequestTimeout) as nobody:
            await comm.request("VisionRequest")
        assert f"nothing on the bus takes requests on {req}" in str(nobody.value)
        assert ("queryable" if queries else "subscriber") in str(nobody.value)

        async with Responder(req, resp, Held({})):  # there, and never answering
            await asyncio.sleep(0.2)  # its subscription and queryable reach the communicator's side
            with pytest.raises(RequestTimeout) as slow:
                await comm.request("VisionRequest")
            assert "nothing on the bus" not in str(slow.value)
