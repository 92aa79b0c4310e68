"""Communicator <-> Responder over real ZeroMQ and over Zenoh (the ``bus`` fixture) on 127.0.0.1: matching, slow joiner, stale/foreign, timeouts."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from aioadept.bus import epypes_pb2
from aioadept.bus.communicator import Communicator
from aioadept.bus.responder import Responder
from aioadept.bus.pairing import Request, Response
from aioadept.bus.messages import EventMessage, decode_event, encode_event
from aioadept.bus.pubsub import Publisher, Subscriber
from aioadept.errors import RemoteError
from aioadept.errors import BusError, ClientStateError, RequestTimeout


class Recorder:
    def __init__(self) -> None:
        self.requests: list[Request] = []
        self.responses: list[Response] = []
        self.republished: list[Request] = []
        self.first_request = asyncio.Event()

    def on_request(self, r: Request) -> None:
        self.requests.append(r)
        self.first_request.set()

    def on_republish(self, r: Request) -> None:
        self.republished.append(r)

    def on_response(self, r: Response) -> None:
        self.responses.append(r)


@pytest.mark.timeout(10)
async def test_request_gets_matching_response_with_observers_and_t_request(bus):
    calls = []

    def handler(event_type, rid, attrs):
        calls.append((event_type, rid, attrs))
        return {"sharpness": 12.5, "frame_t": attrs["t_request"], "proc_time_ms": 0.1}

    class Broken:  # observer failures are logged, never propagated into the request path
        def on_request(self, r):
            raise RuntimeError("observer bug")

        on_response = on_request

    rec = Recorder()
    async with Responder(bus.any(), bus.any(), handler) as node:
        async with Communicator(node.peer_request_endpoint, node.peer_response_endpoint,
                                observers=[Broken(), rec]) as comm:
            t0 = time.time()
            resp = await comm.request("VisionRequest", {"camera": "c0"})
    assert resp.event_type == "VisionResponse" and resp.attributes["sharpness"] == 12.5
    assert len(resp.id) == 8 and int(resp.id, 16) >= 0
    (etype, rid, attrs), = calls
    assert (etype, rid, attrs["camera"]) == ("VisionRequest", resp.id, "c0")
    assert t0 <= attrs["t_request"] <= time.time() and resp.attributes["frame_t"] == attrs["t_request"]
    assert [r.id for r in rec.requests] == [resp.id] and rec.responses == [resp]
    assert rec.requests[0].attributes["t_request"] == attrs["t_request"]
    assert 0 <= resp.t_send_s <= resp.t_recv_s and resp.t_send_s == rec.requests[0].t_send_s


@pytest.mark.timeout(10)
async def test_responder_started_after_request_was_published_slow_joiner(bus):
    req_ep, resp_ep = bus.fixed(), bus.fixed()
    rec = Recorder()
    async with Communicator(req_ep, resp_ep, observers=[rec], timeout_s=5.0) as comm:
        pending = asyncio.create_task(comm.request("VisionRequest", {"n": 1}))
        await rec.first_request.wait()  # published into the void: nobody is bound yet
        async with Responder(req_ep, resp_ep, lambda t, i, a: {"echo": a["n"]}) as node:
            resp = await pending
        assert resp.attributes == {"echo": 1}
        assert comm.republished >= 1 and node.handled == 1
        # Observers saw one request, its re-publications (same id, later times) and one response.
        assert [r.id for r in rec.requests] == [resp.id] and [r.id for r in rec.responses] == [resp.id]
        assert len(rec.republished) == comm.republished
        assert all(r.id == resp.id and r.t_send_s > resp.t_send_s for r in rec.republished)


@pytest.mark.timeout(10)
async def test_stale_and_foreign_responses_are_ignored(bus):
    # A hand-made node: before each right answer it publishes an answer to the previously answered id (stale) and
    # to an id nobody asked for (foreign). It answers every copy it receives, so lost answers are repaired by the
    # communicator's re-publication like with a real node.
    async with Subscriber(bus.any(), bind=True, queries=True) as req_sub, Publisher(bus.any()) as resp_pub:
        async def node():
            answered: list[str] = []
            while True:
                _, rid, attrs = decode_event((await req_sub.recv())[1])
                if answered and answered[-1] != rid:
                    resp_pub.send_nowait(encode_event("VisionResponse", answered[-1], {"v": "stale"}))
                resp_pub.send_nowait(encode_event("VisionResponse", "f0reign1", {"v": "foreign"}))
                resp_pub.send_nowait(encode_event("VisionResponse", rid, {"v": f"right-{attrs['k']}"}))
                if rid not in answered:
                    answered.append(rid)

        async with Communicator(">" + req_sub.actual_endpoint, resp_pub.actual_endpoint) as comm:
            task = asyncio.create_task(node())
            try:
                r1 = await comm.request("VisionRequest", {"k": 1})
                r2 = await comm.request("VisionRequest", {"k": 2})
            finally:
                task.cancel()
            assert (r1.attributes["v"], r2.attributes["v"]) == ("right-1", "right-2")
            assert r1.id != r2.id
            # At least the foreign answer before r1 and the stale + foreign answers before r2 reached us.
            assert comm.ignored_responses >= 3


@pytest.mark.timeout(10)
async def test_timeout_raises_request_timeout_and_republishes_same_id(bus):
    async with Subscriber(bus.any(), bind=True, queries=True) as req_sub, Publisher(bus.any()) as resp_pub:
        async with Communicator(">" + req_sub.actual_endpoint, resp_pub.actual_endpoint,
                                republish_interval_s=0.01, republish_backoff=1.5) as comm:
            got: list[bytes] = []

            async def silent_node():  # reads requests (so its subscription is live) and never answers
                while True:
                    got.append((await req_sub.recv())[1])

            node = asyncio.create_task(silent_node())
            try:
                with pytest.raises(RequestTimeout) as info:
                    await comm.request("VisionRequest", {"x": 1.0}, timeout_s=0.3)
            finally:
                node.cancel()
            assert isinstance(info.value, TimeoutError) and isinstance(info.value, BusError)
            rid = info.value.request_id
            assert len(rid) == 8 and info.value.extra["publishes"] >= 3
            # What the node received: one id, re-published as identical bytes.
            assert len(got) >= 2 and len(set(got)) == 1 and decode_event(got[0])[1] == rid
            # A late answer to the timed-out request is stale: ignored, and the next request still works.
            async def answering_node():  # answers each new request, after a late answer to the timed-out one
                while True:
                    _, rid2, _ = decode_event((await req_sub.recv())[1])
                    if rid2 != rid:
                        resp_pub.send_nowait(encode_event("VisionResponse", rid, {"late": 1}))
                        resp_pub.send_nowait(encode_event("VisionResponse", rid2, {"ok": 1}))

            ignored = comm.ignored_responses
            task = asyncio.create_task(answering_node())
            try:
                nxt = await comm.request("VisionRequest", {"x": 2.0}, timeout_s=5)
            finally:
                task.cancel()
            assert nxt.attributes == {"ok": 1} and nxt.id != rid and comm.ignored_responses > ignored


@pytest.mark.timeout(10)
async def test_concurrent_requests_are_routed_by_id_when_answered_out_of_order(bus):
    async with Subscriber(bus.any(), bind=True, queries=True) as req_sub, Publisher(bus.any()) as resp_pub:
        ids: dict[int, str] = {}

        async def node():  # collects all five, answers them in reverse order, then answers any repeat at once
            while True:
                _, rid, attrs = decode_event((await req_sub.recv())[1])
                n = attrs["n"]
                if len(ids) == 5:
                    resp_pub.send_nowait(encode_event("VisionResponse", rid, {"n2": n * n}))
                    continue
                ids[n] = rid
                if len(ids) == 5:
                    for m in reversed(range(5)):
                        resp_pub.send_nowait(encode_event("VisionResponse", ids[m], {"n2": m * m}))

        async with Communicator(">" + req_sub.actual_endpoint, resp_pub.actual_endpoint) as comm:
            task = asyncio.create_task(node())
            try:
                results = await asyncio.gather(
                    *(comm.request("VisionRequest", {"n": n}) for n in range(5)))
            finally:
                task.cancel()
    assert [r.attributes["n2"] for r in results] == [n * n for n in range(5)]
    assert [r.id for r in results] == [ids[n] for n in range(5)] and len(set(ids.values())) == 5


@pytest.mark.timeout(10)
async def test_repeated_id_is_answered_from_cache_not_reprocessed(bus):
    calls = []

    async def handler(t, rid, attrs):
        calls.append(rid)
        return {"count": len(calls)}

    async with Responder(bus.any(), bus.any(), handler, cache_size=2) as node:
        async with Communicator(node.peer_request_endpoint, node.peer_response_endpoint) as comm:
            async def ask(rid: str) -> int:
                return (await comm.request("VisionRequest", id=rid)).attributes["count"]

            assert await ask("aaaaaaaa") == 1
            hits = node.cache_hits
            assert await ask("aaaaaaaa") == 1  # same id again: the cached answer
            # The node handles requests in order, so once "b" is answered the repeat of "a" has been served.
            assert await ask("bbbbbbbb") == 2
            assert calls == ["aaaaaaaa", "bbbbbbbb"] and node.cache_hits > hits
            # LRU of 2: after "b" and "c", "a" is evicted and processed again.
            assert await ask("cccccccc") == 3
            assert await ask("aaaaaaaa") == 4
            assert calls == ["aaaaaaaa", "bbbbbbbb", "cccccccc", "aaaaaaaa"]
            first = asyncio.create_task(ask("dddddddd"))
            await asyncio.sleep(0)  # let it register its id (ordering, not readiness)
            with pytest.raises(ClientStateError):  # an id may be outstanding only once
                await ask("dddddddd")
            assert await first == 5


@pytest.mark.timeout(10)
async def test_handler_errors_become_error_attribute_and_node_keeps_serving(bus):
    def handler(t, rid, attrs):
        if attrs.get("fail"):
            raise LookupError("no object found")
        if attrs.get("bad"):
            return {"flag": True}  # bool cannot be carried
        return {"ok": 1}

    async with Responder(bus.any(), bus.any(), handler) as node:
        async with Communicator(node.peer_request_endpoint, node.peer_response_endpoint) as comm:
            r1 = await comm.request("VisionRequest", {"fail": 1})
            r2 = await comm.request("VisionRequest", {"bad": 1})
            r3 = await comm.request("VisionRequest", {})
    assert r1.error == "no object found" and r1.attributes == {"error": "no object found"}
    with pytest.raises(RemoteError) as info:
        r1.raise_for_error()
    assert info.value.attributes == {"error": "no object found"}
    assert r2.error.startswith("response not encodable")
    assert r3.attributes == {"ok": 1} and r3.raise_for_error() is r3 and node.errors == 2


@pytest.mark.timeout(10)
async def test_sync_handler_in_thread_does_not_block_the_loop(bus):
    release = threading.Event()
    threads = []

    def slow_graph(t, rid, attrs):
        threads.append(threading.current_thread().name)
        release.wait(5)
        return {"sharpness": 1.0}

    async with Responder(bus.any(), bus.any(), slow_graph, in_thread=True) as node:
        async with Communicator(node.peer_request_endpoint, node.peer_response_endpoint,
                                republish_interval_s=0.002, republish_backoff=1.0) as comm:
            task = asyncio.create_task(comm.request("VisionRequest", {}))
            # The loop stays responsive while the handler blocks its worker thread, and the requester keeps
            # re-publishing the same id meanwhile.
            while not threads or comm.republished < 3:
                await asyncio.sleep(0.002)
            assert not task.done()
            release.set()
            resp = await task
    assert resp.attributes == {"sharpness": 1.0} and threads[0].startswith("aioadept-responder")
    assert node.handled == 1  # re-publications during the slow run were not processed again


@pytest.mark.timeout(10)
async def test_paper_style_send_recv_and_topics(bus):
    async with Responder(bus.any(), bus.any(), lambda t, i, a: {"sharpness": 2.0}, request_topic="vision.req",
                         response_topic="vision.resp") as node:
        async with Communicator(node.peer_request_endpoint, node.peer_response_endpoint,
                                request_topic="vision.req", response_topic="vision.resp") as comm:
            pb_req = epypes_pb2.Event(type="VisionRequest")
            rid = await comm.send(pb_req)
            rid2 = await comm.send(EventMessage("VisionRequest", "0000abcd"))
            pb_resp = await comm.recv()
            assert isinstance(pb_resp, epypes_pb2.Event) and pb_resp.id == rid
            assert {e.key: e.double_val for e in pb_resp.attributes.entries} == {"sharpness": 2.0}
            assert (await comm.recv()).id == rid2 == "0000abcd"
            with pytest.raises(ClientStateError):
                await comm.recv()


@pytest.mark.timeout(10)
async def test_close_fails_outstanding_and_state_errors(bus):
    async with Subscriber(bus.any(), bind=True, queries=True) as req_sub, Publisher(bus.any()) as resp_pub:
        comm = Communicator(">" + req_sub.actual_endpoint, resp_pub.actual_endpoint)
        with pytest.raises(ClientStateError):
            await comm.request()
        async with comm:
            task = asyncio.create_task(comm.request(timeout_s=5))
            await req_sub.recv()  # it was published
            with pytest.raises(ClientStateError):
                await comm.__aenter__()
        with pytest.raises(BusError, match="closed"):
            await task
        with pytest.raises(ClientStateError):
            await comm.request()


@pytest.mark.timeout(15)
async def test_requests_that_timed_out_while_the_node_was_down_are_not_processed_after_its_restart(bus):
    req_ep, resp_ep = bus.fixed(), bus.fixed()
    seen: list[str] = []

    def handler(event_type, rid, attrs):
        seen.append(rid)
        return {"ok": 1}

    async with Communicator(req_ep, resp_ep, republish_interval_s=0.01, republish_backoff=1.0) as comm:
        async with Responder(req_ep, resp_ep, handler):
            first = await comm.request("VisionRequest", {}, timeout_s=5)
        # The node is gone, but the publisher knew its subscription: what it publishes now must not queue up.
        with pytest.raises(RequestTimeout) as info:
            await comm.request("VisionRequest", {}, timeout_s=0.3)
        stale = info.value.request_id
        async with Responder(req_ep, resp_ep, handler):  # the node restarts on the same endpoints
            resp = await comm.request("VisionRequest", {}, timeout_s=5)
    assert resp.attributes == {"ok": 1}
    assert stale not in seen, "a request whose requester gave up was queued and processed after the restart"
    assert seen == [first.id, resp.id]


@pytest.mark.timeout(10)
async def test_plain_handler_may_answer_at_once_or_return_an_awaitable_and_answers_keep_arrival_order(bus):
    release = asyncio.Event()
    calls: list[str] = []

    def handler(event_type, rid, attrs):
        calls.append(attrs["name"])
        if attrs["name"] == "slow":
            async def later():
                await release.wait()
                return {"name": "slow"}
            return later()
        return {"name": attrs["name"]}

    async with Responder(bus.any(), bus.any(), handler) as node, \
            Communicator(node.peer_request_endpoint, node.peer_response_endpoint, timeout_s=5) as comm:
        assert (await comm.request("VisionRequest", {"name": "quick"})).attributes["name"] == "quick"
        order: list[str] = []

        async def ask(name):
            resp = await comm.request("VisionRequest", {"name": name})
            order.append(resp.attributes["name"])

        slow = asyncio.create_task(ask("slow"))
        while "slow" not in calls:  # the node has received it (and is waiting on release)
            await asyncio.sleep(0.01)
        quick = asyncio.create_task(ask("after-slow"))
        await asyncio.sleep(0.1)
        assert order == [], "a request behind a waiting one must not be answered first"
        release.set()
        await asyncio.gather(slow, quick)
    assert order == ["slow", "after-slow"]
    assert node.handled == 3 and node.errors == 0


async def until(predicate, timeout_s: float = 5.0) -> bool:
    """Poll ``predicate`` on the loop until it holds or ``timeout_s`` passes (no readiness sleep: a deadline)."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            return False
        await asyncio.sleep(0.01)
    return True


@pytest.mark.timeout(15)
async def test_send_without_recv_leaves_no_pending_entries_on_any_path(bus, monkeypatch):
    # Answered: the entries leave the registry when the answers arrive, not when recv() takes them.
    async with Responder(bus.any(), bus.any(), lambda t, i, a: {"ok": 1}) as node:
        async with Communicator(node.peer_request_endpoint, node.peer_response_endpoint) as comm:
            first = await comm.send(EventMessage("VisionRequest", "000000a1"))
            second = await comm.send(EventMessage("VisionRequest", "000000a2"))
            assert await until(lambda: comm.pending_ids == ()), comm.pending_ids
            assert node.handled == 2
            # The outcomes are kept for recv(), in send order.
            assert (await comm.recv()).id == first and (await comm.recv()).id == second
    # Timed out, and closed: nobody ever calls recv().
    async with Subscriber(bus.any(), bind=True, queries=True) as req_sub:
        async with Communicator(">" + req_sub.actual_endpoint, bus.nowhere(), timeout_s=0.2) as comm:
            await comm.send(EventMessage("VisionRequest", "000000b1"))
            assert comm.pending_ids == ("000000b1",)
            assert await until(lambda: comm.pending_ids == ()), comm.pending_ids
            with pytest.raises(RequestTimeout):
                await comm.recv()
            await comm.send(EventMessage("VisionRequest", "000000b2"))
            # The id is free again once settled, even before recv().
            await comm.send(EventMessage("VisionRequest", "000000b1"))
        assert comm.pending_ids == ()
        # More sends than are kept without recv(): the oldest is forgotten (and not pending).
        monkeypatch.setattr("aioadept.bus.communicator.MAX_UNRECEIVED", 2)
        async with Communicator(">" + req_sub.actual_endpoint, bus.nowhere(), timeout_s=5) as comm:
            ids = [await comm.send(EventMessage("VisionRequest")) for _ in range(3)]
            assert comm.pending_ids == tuple(ids[1:])
            task = asyncio.ensure_future(comm.recv())
            await until(lambda: False, 0.05)
            assert not task.done()
        with pytest.raises(BusError, match="closed"):
            await task


@pytest.mark.timeout(10)
async def test_a_cancelled_request_leaves_no_pending_entry(bus):
    async with Subscriber(bus.any(), bind=True, queries=True) as req_sub:
        async with Communicator(">" + req_sub.actual_endpoint, bus.nowhere(), timeout_s=5) as comm:
            task = asyncio.create_task(comm.request())
            await req_sub.recv()
            assert len(comm.pending_ids) == 1
            task.cancel()
            with pytest.raises(asyncio.CancelledError):
                await task
            assert comm.pending_ids == ()
