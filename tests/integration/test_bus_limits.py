"""Responder limits over real ZeroMQ on 127.0.0.1: the bounded request queue and its drop rule,
``t_deadline`` that is not a finite number, and the request size limit (``ZMQ_MAXMSGSIZE``).

Raw pyzmq sockets stand in for the requester where the Communicator's own behaviour (re-publishing, setting
``t_deadline``) would hide what the node does with each single request.
"""

from __future__ import annotations

import asyncio
import math

import pytest
import zmq
import zmq.asyncio

from aioadept.bus.responder import DEFAULT_MAX_QUEUE, DEFAULT_MAX_REQUEST_BYTES, Responder
from aioadept.bus.communicator import Communicator
from aioadept.bus.messages import decode_event, encode_event

ANY = "tcp://127.0.0.1:*"


class RawRequester:
    """A plain PUB (requests) and SUB (responses) connected to a Responder; collects responses by id."""

    def __init__(self, request_ep: str, response_ep: str) -> None:
        self.ctx = zmq.asyncio.Context()
        self.pub = self.ctx.socket(zmq.PUB)
        self.pub.setsockopt(zmq.LINGER, 0)
        self.pub.setsockopt(zmq.SNDHWM, 0)  # never drop on our side: what is lost, the node lost
        self.pub.connect(request_ep)
        self.sub = self.ctx.socket(zmq.SUB)
        self.sub.setsockopt(zmq.LINGER, 0)
        self.sub.setsockopt(zmq.RCVHWM, 0)
        self.sub.setsockopt(zmq.SUBSCRIBE, b"")
        self.sub.connect(response_ep)
        self.answers: dict[str, dict] = {}
        self._arrived = asyncio.Event()
        self._reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        while True:
            _type, rid, attrs = decode_event(await self.sub.recv())
            self.answers.setdefault(rid, attrs)
            self._arrived.set()

    def send(self, rid: str, attrs: dict | None = None) -> None:
        self.pub.send(encode_event("VisionRequest", rid, attrs or {}))

    async def ask(self, rid: str, attrs: dict | None = None, *, every_s: float = 0.05) -> dict:
        """Send until answered (the slow joiner, a reconnect): a poll with no other deadline than the test's."""
        while rid not in self.answers:
            self.send(rid, attrs)
            self._arrived.clear()
            try:
                async with asyncio.timeout(every_s):
                    await self._arrived.wait()
            except TimeoutError:
                pass
        return self.answers[rid]

    async def wait_for(self, rids: set[str]) -> None:
        while not rids <= self.answers.keys():
            self._arrived.clear()
            await self._arrived.wait()

    async def close(self) -> None:
        self._reader.cancel()
        try:
            await self._reader
        except asyncio.CancelledError:
            pass
        self.pub.close(0)
        self.sub.close(0)
        self.ctx.term()


def test_the_documented_defaults():
    assert DEFAULT_MAX_QUEUE == 32 and DEFAULT_MAX_REQUEST_BYTES == 1 << 20
    for bad in ({"max_queue": 0}, {"max_queue": 1.5}, {"max_request_bytes": 0}, {"max_request_bytes": True}):
        with pytest.raises(ValueError):
            Responder(ANY, ANY, lambda *a: {}, **bad)


@pytest.mark.timeout(20)
async def test_a_full_queue_drops_the_oldest_waiting_request_with_an_error():
    calls: list[str] = []
    started, release = asyncio.Event(), asyncio.Event()

    async def handler(_type, rid, _attrs):
        calls.append(rid)
        if rid == "aaaaaaaa":
            started.set()
            await release.wait()
        return {"rid": rid}

    async with Responder(ANY, ANY, handler, max_queue=3) as node:
        req = RawRequester(node.actual_request_endpoint, node.actual_response_endpoint)
        try:
            await req.ask("00000000")  # both paths joined
            req.send("aaaaaaaa")
            async with asyncio.timeout(5):
                await started.wait()  # the node is busy with "a": what comes now waits in its queue
            later = [f"b000000{i}" for i in range(1, 7)]
            for rid in later:
                req.send(rid)
            async with asyncio.timeout(5):
                await req.wait_for(set(later[:3]))  # the three oldest are dropped as the newer ones arrive
            assert calls == ["00000000", "aaaaaaaa"]  # ... without being processed
            release.set()
            async with asyncio.timeout(5):
                await req.wait_for({"aaaaaaaa", *later})
        finally:
            await req.close()
    for rid in later[:3]:
        err = req.answers[rid]["error"]
        assert err.startswith("dropped: request queue full (3 waiting)") and "newest" in err, err
    assert [req.answers[rid] for rid in later[3:]] == [{"rid": rid} for rid in later[3:]]
    assert calls == ["00000000", "aaaaaaaa", *later[3:]]  # the newest, in arrival order
    assert node.dropped == 3 and node.handled == 5


@pytest.mark.timeout(20)
async def test_t_deadline_that_is_not_a_finite_number_is_answered_with_an_error():
    calls: list[str] = []

    def handler(_type, rid, _attrs):
        calls.append(rid)
        return {"ok": 1}

    bad = [math.nan, math.inf, -math.inf, "soon", ""]
    async with Responder(ANY, ANY, handler) as node:
        req = RawRequester(node.actual_request_endpoint, node.actual_response_endpoint)
        try:
            assert await req.ask("00000000") == {"ok": 1}
            answers = [await req.ask(f"dead000{i}", {"t_deadline": d}) for i, d in enumerate(bad)]
            far = await req.ask("0000f000", {"t_deadline": 2_000_000_000})  # an int (2033): fine
        finally:
            await req.close()
    for d, attrs in zip(bad, answers, strict=True):
        assert attrs == {"error": f"bad request: t_deadline must be a finite number (epoch s), got {d!r}"}
    assert far == {"ok": 1}
    assert calls == ["00000000", "0000f000"] and node.rejected == len(bad)


@pytest.mark.timeout(20)
async def test_the_communicator_refuses_bad_times_before_sending():
    calls: list[str] = []
    async with Responder(ANY, ANY, lambda _t, rid, _a: calls.append(rid) or {"ok": 1}) as node, \
            Communicator(node.peer_request_endpoint, node.peer_response_endpoint, timeout_s=5.0) as comm:
        for attrs in ({"t_deadline": math.nan}, {"t_request": math.inf}, {"t_request": "now"},
                      {"t_deadline": True}):
            with pytest.raises(ValueError, match="must be a finite number"):
                await comm.request("VisionRequest", attrs)
        for timeout in (math.nan, math.inf, 0, -1.0):
            with pytest.raises(ValueError, match="timeout_s"):
                await comm.request("VisionRequest", {}, timeout_s=timeout)
        assert comm.pending_ids == ()
        ok = await comm.request("VisionRequest", {})
    assert ok.attributes == {"ok": 1} and len(calls) == 1
    for bad in ({"timeout_s": math.nan}, {"republish_interval_s": math.inf}, {"republish_backoff": math.nan}):
        with pytest.raises(ValueError):
            Communicator(**bad)


@pytest.mark.timeout(20)
async def test_a_request_over_the_size_limit_is_dropped_unparsed_and_the_node_keeps_serving():
    calls: list[str] = []

    def handler(_type, rid, _attrs):
        calls.append(rid)
        return {"ok": 1}

    async with Responder(ANY, ANY, handler, max_request_bytes=1000) as node:
        req = RawRequester(node.actual_request_endpoint, node.actual_response_endpoint)
        try:
            await req.ask("00000000")
            req.send("0b160000", {"blob": "x" * 2000})  # over the limit: ZeroMQ disconnects us ...
            # ... and reconnects; a small request sent after it (re-sent until through) is answered. Had the big
            # one been read, its answer would have come first: requests from one PUB arrive in order.
            assert await req.ask("5a115a11", {"blob": "x" * 500}) == {"ok": 1}
        finally:
            await req.close()
    assert "0b160000" not in req.answers and "0b160000" not in calls
    assert calls[0] == "00000000" and "5a115a11" in calls
