"""Publisher/Subscriber over real ZeroMQ on 127.0.0.1 (ports chosen by the OS)."""

from __future__ import annotations

import asyncio
import threading

import pytest
import zmq
import zmq.asyncio

from aioadept.bus.pubsub import Publisher, Subscriber, SyncPublisher, SyncSubscriber
from aioadept.errors import BusError

ANY = "tcp://127.0.0.1:*"


async def recv_while_publishing(sub: Subscriber, send, *, every_s: float = 0.005):
    """Re-send until the subscriber gets something: the slow-joiner cure used in place of a readiness sleep."""
    rx = asyncio.ensure_future(sub.recv())
    try:
        while not rx.done():
            send()
            await asyncio.wait({rx}, timeout=every_s)
        return rx.result()
    finally:
        rx.cancel()


@pytest.mark.timeout(10)
async def test_bound_port_zero_resolves_and_topic_frames_arrive():
    async with Subscriber("tcp://127.0.0.1:0", bind=True, topics=["robot.state"]) as sub:
        port = int(sub.actual_endpoint.rsplit(":", 1)[1])
        assert port > 0 and sub.actual_endpoint.startswith("tcp://127.0.0.1:")
        async with Publisher(sub.actual_endpoint, bind=False) as pub:
            def send():
                pub.publish_nowait(b"other", b"nope")
                pub.publish_nowait("robot.state", b"\x01\x02")
            topic, payload = await recv_while_publishing(sub, send)
            assert (topic, payload) == (b"robot.state", b"\x01\x02")
            # Topic filtering: nothing but robot.state ever arrives, even though "other" went first each time.
            await pub.publish("robot.state", b"last")
            while (msg := await sub.recv()) != (b"robot.state", b"last"):
                assert msg[0] == b"robot.state"


@pytest.mark.timeout(10)
async def test_single_frame_send_arrives_with_empty_topic(bus):
    async with Publisher(bus.any()) as pub, Subscriber(pub.actual_endpoint) as sub:
        assert await recv_while_publishing(sub, lambda: pub.send_nowait(b"epypes-style")) == (b"", b"epypes-style")
        await pub.send(b"again")
        while (msg := await sub.recv()) != (b"", b"again"):
            assert msg == (b"", b"epypes-style")


@pytest.mark.timeout(10)
async def test_sync_publisher_from_a_thread(bus):
    async with Subscriber(bus.any(), bind=True, topics=[b"t"]) as sub:
        stop = threading.Event()

        def worker():
            with SyncPublisher(sub.actual_endpoint, bind=False) as pub:
                while not stop.is_set():  # republish until the test has its message (slow joiner)
                    pub.publish("t", b"from-thread")
                    stop.wait(0.005)

        th = threading.Thread(target=worker)
        th.start()
        try:
            assert await sub.recv() == (b"t", b"from-thread")
        finally:
            stop.set()
            await asyncio.to_thread(th.join)


@pytest.mark.timeout(10)
async def test_errors_are_bus_errors_and_close_is_idempotent():
    pub = Publisher(ANY)
    with pytest.raises(BusError):
        Publisher(pub.actual_endpoint)  # address in use
    with pytest.raises(BusError):
        Subscriber("not-a-transport://x")
    pub.close()
    pub.close()
    assert pub.closed
    with pytest.raises(BusError):
        pub.publish_nowait("t", b"x")
    sub = Subscriber(ANY, bind=True)
    rx = asyncio.ensure_future(sub.recv())
    await asyncio.sleep(0)  # let recv() start waiting; this is ordering, not readiness
    sub.close()
    with pytest.raises(BusError):
        await rx
    with pytest.raises(BusError):
        await sub.recv()


@pytest.mark.timeout(10)
async def test_own_context_is_used_and_not_terminated():
    ctx = zmq.asyncio.Context()
    try:
        async with Publisher(ANY, context=ctx) as pub, Subscriber(pub.actual_endpoint, context=ctx) as sub:
            assert pub._sock.context.underlying == ctx.underlying
            assert await recv_while_publishing(sub, lambda: pub.send_nowait(b"x")) == (b"", b"x")
        assert not ctx.closed
        # A plain (sync) context works as well: the subscriber shadows it without owning it.
        sync_ctx = zmq.Context()
        async with Subscriber(ANY, bind=True, context=sync_ctx) as sub2:
            assert sub2._sock.context.underlying == sync_ctx.underlying
        assert not sync_ctx.closed
        sync_ctx.term()
    finally:
        ctx.term()


@pytest.mark.timeout(10)
def test_sync_subscriber_in_a_plain_thread_gets_topic_frames_and_times_out():
    # The role the virtual camera's robot-state reader uses: a SUB for one plain thread, with a receive timeout.
    with SyncPublisher(ANY) as pub, SyncSubscriber(">" + pub.actual_endpoint, topics=("robot.state",)) as sub:
        assert not sub.bound and sub.topics == (b"robot.state",)
        assert sub.recv(timeout_s=0.0) is None  # nothing yet: None, never a hang
        got = None
        for _ in range(500):  # slow joiner: publish until the subscription is live (a retry, not a sleep)
            pub.publish("other.topic", b"not for us")
            pub.publish("robot.state", b"sample")
            got = sub.recv(timeout_s=0.01)
            if got is not None:
                break
        assert got == (b"robot.state", b"sample")
        with pytest.raises(ValueError):
            sub.recv(timeout_s=-1)
    assert sub.closed and pub.closed
    with pytest.raises(BusError):
        sub.recv(timeout_s=0.0)
    with pytest.raises(BusError, match="cannot connect"):
        SyncSubscriber(">tcp://127.0.0.1:notaport")
