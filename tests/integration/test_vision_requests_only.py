"""The vision node serves only requests, over real ZeroMQ on 127.0.0.1.

Events of another type on its request port (a ``Shutdown``, a ``VisionResponse`` sent back to it) are ignored and
counted: none takes a frame, runs a graph, holds a queue slot or gets an answer published.
"""

from __future__ import annotations

import asyncio
import time

import cv2
import numpy as np
import pytest
import zmq
import zmq.asyncio

from aioadept.bus.messages import decode_event, encode_event

pytestmark = pytest.mark.timeout(30)


def _addr(endpoint: str) -> str:
    """``>tcp://127.0.0.1:1234`` (the form a peer uses) -> ``tcp://127.0.0.1:1234``."""
    return endpoint.lstrip(">@")


async def _until_answered(pub, sub, rid: str, seen: list[tuple[str, str | None]], *, timeout_s: float = 10.0) -> None:
    """Publish a VisionRequest ``rid`` (again every 50 ms: the slow joiner; repeats are answered from the node's
    cache) until its answer arrives; every event received on the way is appended to ``seen``."""
    async with asyncio.timeout(timeout_s):
        while True:
            await pub.send(encode_event("VisionRequest", rid, {"t_request": time.time()}))
            while await sub.poll(50):
                etype, eid, _attrs = decode_event((await sub.recv_multipart())[-1])
                seen.append((etype, eid))
                if eid == rid:
                    return


async def test_shutdown_and_response_events_on_the_request_port_are_ignored_and_counted(tmp_path):
    from aioadept.vision.acquisition import Acquisition
    from aioadept.vision.node import NodeResponder, VisionNode, noop_graph
    from aioadept.vision.sources import ImageFolderSource

    cv2.imwrite(str(tmp_path / "0.png"), np.full((48, 64), 20, np.uint8))
    ctx = zmq.asyncio.Context()
    with Acquisition([ImageFolderSource(tmp_path, loop=True)], fps=50) as acq:
        assert await asyncio.to_thread(acq.wait_ready, 5.0)
        # policy "after", max_queue 2: had a foreign event been taken for a request, it would wait for a frame and
        # hold a queue slot, and ten of them would push the real request out ("dropped").
        node = VisionNode(acq, noop_graph(), policy="after", timeout_s=2.0, max_frame_age_s=1.0)
        try:
            async with NodeResponder("tcp://127.0.0.1:0", "tcp://127.0.0.1:0", node, max_queue=2) as responder:
                pub = ctx.socket(zmq.PUB)
                sub = ctx.socket(zmq.SUB)
                sub.setsockopt(zmq.SUBSCRIBE, b"")
                pub.connect(_addr(responder.peer_request_endpoint))
                sub.connect(_addr(responder.peer_response_endpoint))
                try:
                    seen: list[tuple[str, str | None]] = []
                    await _until_answered(pub, sub, "first001", seen)  # both connections are up
                    served_before = node.served
                    for i in range(10):
                        await pub.send(encode_event("Shutdown", f"shut{i:04d}", {}))
                        await pub.send(encode_event("VisionResponse", f"resp{i:04d}", {"sharpness": 1.0}))
                    seen.clear()
                    # Same connection, so it arrives after the twenty foreign events and is served after them.
                    await _until_answered(pub, sub, "last0001", seen)
                finally:
                    pub.close(linger=0)
                    sub.close(linger=0)
        finally:
            node.close()
    ctx.term()
    assert seen and {eid for _t, eid in seen} == {"last0001"}, seen  # nothing answered but the request
    assert [t for t, _eid in seen] == ["VisionResponse"] * len(seen)
    assert node.served - served_before == 1  # one frame taken: the request's
    assert responder.ignored == 20
    assert responder.dropped == 0 and responder.errors == 0
