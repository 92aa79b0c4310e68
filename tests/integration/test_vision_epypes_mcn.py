"""The paper's MasterControlNode, as pyadept builds it, against ``aioadept sim`` + ``aioadept vision`` with only
addresses configured (the recipe of docs/interfaces.md).

pyadept is not on PyPI, so its request/response path is re-created here in raw pyzmq: a ``PubSubPair`` that
**binds its request PUB** and **connects its response SUB**, sending single-frame EPypes ``Event`` messages built
from EPypes' own schema (tests/unit/bus/epypes_reference.py, not our generated code). The vision node is started
with bare addresses: it connects its request SUB and binds its response PUB, as every EPypes node does. Nothing
says ``@``, ``>`` or ``bind=``. The MCN then runs the paper's ufloop: a step along tool z, a request, until the
sharpness drops; the peak must be on the virtual camera's focal plane.
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib.util
import time
from pathlib import Path

import pytest
import zmq

from aioadept import MoveJoints, MoveRelJoints, MoveRelTool, MoveToolZ, SetSpeed
from aioadept.client import RobotClient
from aioadept.testing.nodes import running_node
from aioadept.ports import free_port

_spec = importlib.util.spec_from_file_location(
    "epypes_reference", Path(__file__).parents[1] / "unit" / "bus" / "epypes_reference.py")
ref = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ref)


def attrs_of(pb) -> dict:
    """EPypes' get_attributes_dict."""
    return {e.key: e.str_val if e.type == 1 else e.double_val if e.type == 2 else e.int_val
            for e in pb.attributes.entries}


class PubSubPair:
    """pyadept's PubSubPair socket pattern: PUB binds (requests out), SUB connects with prefix "" (responses in)."""

    def __init__(self, pub_address: str, sub_address: str) -> None:
        self.ctx = zmq.Context()
        self.pub, self.sub = self.ctx.socket(zmq.PUB), self.ctx.socket(zmq.SUB)
        for s in (self.pub, self.sub):
            s.setsockopt(zmq.LINGER, 0)
        self.sub.setsockopt_string(zmq.SUBSCRIBE, "")
        self.pub.bind(pub_address)
        self.sub.connect(sub_address)
        self.n = 0

    def request(self, timeout_s: float = 10.0) -> dict:
        """One VisionRequest; the same bytes again every 50 ms until its answer (ZeroMQ's slow joiner)."""
        self.n += 1
        req = ref.Event(type="VisionRequest", id=f"mcn{self.n:05d}")
        ref.add_attribute(req, "t_request", time.time())
        payload = req.SerializeToString()
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self.pub.send(payload)
            while self.sub.poll(50):
                resp = ref.Event()
                resp.ParseFromString(self.sub.recv())
                if resp.id == req.id:
                    assert resp.type == "VisionResponse"
                    return attrs_of(resp)
        raise TimeoutError(f"no answer to {req.id} within {timeout_s} s")

    def close(self) -> None:
        self.pub.close()
        self.sub.close()
        self.ctx.term()


@pytest.mark.timeout(90)
async def test_pyadept_mcn_runs_ufloop_against_sim_and_vision_with_addresses_only(tmp_path):
    request_address = f"tcp://127.0.0.1:{free_port()}"
    async with running_node("sim", "--port", "0", "--time-scale", "10", "--state-endpoint", "tcp://127.0.0.1:0",
                            log_path=tmp_path / "sim.log") as sim, \
            running_node("vision", "--state-endpoint", sim.ready["state"], "--request-endpoint", request_address,
                         "--response-endpoint", "tcp://127.0.0.1:0", "--seed", "5",
                         log_path=tmp_path / "vision.log") as vis:
        # The node connected its request SUB (the MCN must bind there) and bound its response PUB.
        assert vis.ready["request"] == "@" + request_address
        assert vis.ready["response"].startswith(">tcp://127.0.0.1:")
        response_address = vis.ready["response"][1:]  # the address alone, as an MCN's config file would hold it
        mcn = PubSubPair(request_address, response_address)
        try:
            async with RobotClient(sim.ready["host"], int(sim.ready["port"])) as robot:
                await robot.cmdexec(MoveJoints([0, -90, 180, 0, 90, 0]), MoveRelJoints([-90, 60, 30, -90, 0, 0]),
                                    MoveRelTool([40, -25, 185, 0, 0, 0]), MoveRelJoints([0, 0, 0, 0, 0, 1.5]))
                sharpness = []
                for _ in range(14):  # ufloop: measure, step 2 mm along tool z
                    resp = await asyncio.to_thread(mcn.request)
                    assert "error" not in resp, resp
                    sharpness.append(resp["sharpness"])
                    await robot.cmdexec_joined(SetSpeed(25), MoveToolZ(2.0))
        finally:
            with contextlib.suppress(Exception):
                mcn.close()
    peak = max(range(len(sharpness)), key=sharpness.__getitem__)
    assert peak == 10, sharpness  # the focal plane, 20 mm = 10 steps ahead
