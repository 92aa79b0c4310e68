"""Our Communicator against an EPypes-style node, and the paper's MCN (pyadept's PubSubPair) against our Responder,
with only addresses configured: no ``bind=`` argument, no ``@``/``>`` prefix.

The peers are written the way EPypes' zeromq.py / pbprocess.py and pyadept's PubSubPair work: plain pyzmq in a
thread, single-frame messages, SUB with prefix "", message classes built from EPypes' own definitions (not our
generated code), and their socket roles: **every PUB binds, every SUB connects** (the EPypes node binds its response
PUB and connects its request SUB; PubSubPair binds its request PUB and connects its response SUB). They have no
answer cache: they answer every copy they get, so our re-publication still converges.
"""

from __future__ import annotations

import asyncio
import importlib.util
import threading
from pathlib import Path

import pytest
import zmq

from aioadept.bus.communicator import Communicator
from aioadept.bus.responder import Responder
from aioadept.ports import free_port

_spec = importlib.util.spec_from_file_location(
    "epypes_reference", Path(__file__).parents[1] / "unit" / "bus" / "epypes_reference.py")
ref = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ref)


def attrs_of(pb) -> dict:
    """EPypes' get_attributes_dict."""
    return {e.key: e.str_val if e.type == 1 else e.double_val if e.type == 2 else e.int_val
            for e in pb.attributes.entries}


@pytest.mark.timeout(10)
async def test_communicator_with_an_epypes_style_node():
    """EPypes node: its request SUB connects to the MCN's address, its response PUB binds. Our Communicator, given
    just the two addresses, binds the request PUB and connects the response SUB."""
    request_ep = f"tcp://127.0.0.1:{free_port()}"
    ctx = zmq.Context()
    sub, pub = ctx.socket(zmq.SUB), ctx.socket(zmq.PUB)
    for s in (sub, pub):
        s.setsockopt(zmq.LINGER, 0)
    sub.setsockopt_string(zmq.SUBSCRIBE, "")
    sub.connect(request_ep)
    pub.bind("tcp://127.0.0.1:*")
    stop = threading.Event()
    seen = []

    def epypes_node():
        while not stop.is_set():
            if not sub.poll(20):
                continue
            req = ref.Event()
            req.ParseFromString(sub.recv())
            seen.append(attrs_of(req))
            resp = ref.Event(type="VisionResponse", id=req.id)
            ref.add_attribute(resp, "sharpness", 7.25)
            ref.add_attribute(resp, "camera", attrs_of(req).get("camera", ""))
            pub.send(resp.SerializeToString())

    th = threading.Thread(target=epypes_node)
    th.start()
    try:
        async with Communicator(request_ep, pub.getsockopt_string(zmq.LAST_ENDPOINT), timeout_s=5.0) as comm:
            r = await comm.request("VisionRequest", {"camera": "left"})
    finally:
        stop.set()
        await asyncio.to_thread(th.join)
        sub.close()
        pub.close()
        ctx.term()
    assert r.attributes == {"sharpness": 7.25, "camera": "left"}
    assert seen[0]["camera"] == "left" and isinstance(seen[0]["t_request"], float)


@pytest.mark.timeout(10)
async def test_pyadept_pubsubpair_requester_with_our_responder():
    """pyadept's PubSubPair binds its request PUB and connects its response SUB; our Responder, given just the two
    addresses, connects its request SUB and binds its response PUB."""
    request_ep = f"tcp://127.0.0.1:{free_port()}"
    async with Responder(request_ep, "tcp://127.0.0.1:0",
                         lambda t, i, a: {"sharpness": a["n"] * 2.0, "n": a["n"]}) as node:
        assert node.peer_request_endpoint == "@" + request_ep  # the requester binds there
        def pubsubpair_requester() -> dict:
            ctx = zmq.Context()
            pub, sub = ctx.socket(zmq.PUB), ctx.socket(zmq.SUB)
            try:
                for s in (sub, pub):
                    s.setsockopt(zmq.LINGER, 0)
                sub.setsockopt_string(zmq.SUBSCRIBE, "")
                pub.bind(request_ep)
                sub.connect(node.actual_response_endpoint)
                req = ref.Event(type="VisionRequest", id="e9e9e9e9")
                ref.add_attribute(req, "n", 21)
                while True:  # the same request until answered (slow joiner)
                    pub.send(req.SerializeToString())
                    if sub.poll(20):
                        resp = ref.Event()
                        resp.ParseFromString(sub.recv())
                        return {"type": resp.type, "id": resp.id, **attrs_of(resp)}
            finally:
                pub.close()
                sub.close()
                ctx.term()

        got = await asyncio.to_thread(pubsubpair_requester)
    assert got == {"type": "VisionResponse", "id": "e9e9e9e9", "sharpness": 42.0, "n": 21}
    assert node.handled == 1
