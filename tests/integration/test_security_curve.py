"""CURVE on the bus over real ZeroMQ on 127.0.0.1: an authorised subscriber receives, others receive nothing.

The server side's handshake outcomes are read from a ZeroMQ socket monitor, so the tests wait for events (a
refused handshake, an accepted one) instead of sleeping. "Receives nothing" is then shown on messages published
after every refused peer had tried and failed, while the authorised subscriber on the same socket got them all.
"""

from __future__ import annotations

import asyncio

import pytest
import zmq
import zmq.asyncio
from zmq.utils.monitor import parse_monitor_message

from aioadept.bus import security
from aioadept.bus.communicator import Communicator
from aioadept.bus.responder import Responder
from aioadept.bus.pubsub import Publisher, Subscriber
from aioadept.bus.sockets import open_socket
from aioadept.bus.sockets import close_socket
from aioadept.bus.security import CurveClient, CurveKeyPair, CurveServer, load_keypair, save_keypair
from aioadept.errors import RequestTimeout

ANY = "tcp://127.0.0.1:*"
FAILED = {zmq.EVENT_HANDSHAKE_FAILED_AUTH, zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL,
          zmq.EVENT_HANDSHAKE_FAILED_NO_DETAIL}


class Monitor:
    """Handshake events of one socket, counted as they arrive."""

    def __init__(self, sock: zmq.Socket, name: str) -> None:
        addr = f"inproc://monitor-{name}-{id(sock)}"
        sock.monitor(addr, zmq.EVENT_HANDSHAKE_SUCCEEDED | zmq.EVENT_HANDSHAKE_FAILED_AUTH
                     | zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL | zmq.EVENT_HANDSHAKE_FAILED_NO_DETAIL)
        self._mon = zmq.asyncio.Context.instance().socket(zmq.PAIR)
        self._mon.connect(addr)
        self._sock = sock
        self.ok = self.failed = 0

    async def wait(self, *, ok: int = 0, failed: int = 0) -> None:
        while self.ok < ok or self.failed < failed:
            event = parse_monitor_message(await self._mon.recv_multipart())["event"]
            if event == zmq.EVENT_HANDSHAKE_SUCCEEDED:
                self.ok += 1
            elif event in FAILED:
                self.failed += 1

    def close(self) -> None:
        self._sock.disable_monitor()
        self._mon.close(linger=0)


async def receives_within(sub: Subscriber, seconds: float) -> bool:
    try:
        await asyncio.wait_for(sub.recv(), seconds)
    except TimeoutError:
        return False
    return True


@pytest.mark.timeout(20)
async def test_only_the_authorised_subscriber_receives():
    server, good, intruder = CurveKeyPair.generate(), CurveKeyPair.generate(), CurveKeyPair.generate()
    pub, endpoint = open_socket(zmq.PUB, ANY, bind=True, curve=CurveServer(server, allowed_clients=[good.public]))
    mon = Monitor(pub, "pub")
    subs: list[Subscriber] = []
    try:
        ok_sub = Subscriber(endpoint, curve=CurveClient(good, server_public=server.public))
        subs.append(ok_sub)
        await mon.wait(ok=1)
        # Each refused peer is added alone and must fail its handshake before the next one comes.
        bad = {
            "no CURVE": None,
            "key not on the list": CurveClient(intruder, server_public=server.public),
            "wrong server key": CurveClient(good, server_public=intruder.public),
        }
        for i, curve in enumerate(bad.values(), start=1):
            subs.append(Subscriber(endpoint, curve=curve))
            await mon.wait(ok=1, failed=i)
        assert mon.ok == 1  # nobody else got in
        assert security.denied_count(pub) >= 1  # the ZAP handler refused the intruder's key
        # Publish until the authorised subscriber has the marker; everything sent went to every connected peer.
        n = 0
        rx = asyncio.ensure_future(ok_sub.recv())
        while not rx.done():
            pub.send_multipart([b"robot.state", b"%d" % n])
            n += 1
            await asyncio.wait({rx}, timeout=0.005)
        got = [rx.result()]
        pub.send_multipart([b"robot.state", b"last"])
        while got[-1][1] != b"last":
            got.append(await ok_sub.recv())
        assert got[-1] == (b"robot.state", b"last") and len(got) >= 2
        # The refused ones never completed a handshake: nothing reaches them (a bounded negative check, all three
        # at once; not a readiness wait).
        received = await asyncio.gather(*(receives_within(s, 0.3) for s in subs[1:]))
        assert [name for name, r in zip(bad, received, strict=True) if r] == []
    finally:
        for s in subs:
            s.close()
        mon.close()
        close_socket(pub)


@pytest.mark.timeout(20)
async def test_publisher_and_subscriber_classes_with_curve_and_key_files(tmp_path):
    pub_file, secret_file = save_keypair(tmp_path, "node")
    assert (secret_file.stat().st_mode & 0o777) == 0o600
    server = load_keypair(secret_file)
    assert load_keypair(pub_file).secret is None and load_keypair(pub_file).public == server.public
    client = CurveKeyPair.generate()
    async with Publisher(ANY, curve=CurveServer(server, [client.public])) as pub, \
            Subscriber(pub.actual_endpoint, curve=CurveClient(client, load_keypair(pub_file).public)) as sub:
        rx = asyncio.ensure_future(sub.recv())
        while not rx.done():
            pub.publish_nowait("t", b"secret payload")
            await asyncio.wait({rx}, timeout=0.005)
        assert rx.result() == (b"t", b"secret payload")
    # The last secured socket gone, the context's ZAP handler is stopped and a new one can start.
    assert security._auths == {}  # noqa: SLF001


@pytest.mark.timeout(20)
async def test_vision_requests_need_an_authorised_key():
    node, mcn, stranger = CurveKeyPair.generate(), CurveKeyPair.generate(), CurveKeyPair.generate()
    seen: list[str | None] = []

    def handler(event_type, request_id, attributes):
        seen.append(request_id)
        return {"sharpness": 1.5}

    async with Responder(ANY, ANY, handler, curve=CurveServer(node, allowed_clients=[mcn.public])) as responder:
        req, resp = responder.peer_request_endpoint, responder.peer_response_endpoint
        async with Communicator(req, resp, timeout_s=0.5,
                                curve=CurveClient(stranger, server_public=node.public)) as comm:
            with pytest.raises(RequestTimeout):
                await comm.request("VisionRequest")
        assert seen == [] and responder.handled == 0  # the stranger's requests never reached the handler
        async with Communicator(req, resp, timeout_s=5.0, curve=CurveClient(mcn, server_public=node.public)) as comm:
            response = await comm.request("VisionRequest")
        assert response.attributes["sharpness"] == 1.5 and seen == [response.id]
