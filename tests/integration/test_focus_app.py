"""The focus application against the real simulated controller and a scripted vision node over real ZeroMQ.

The vision side is a real :class:`~aioadept.bus.Responder` whose handler plays back a sharpness series, so each
branch of ``ufloop`` (peak found, step limit, vision error, vision silent, stop event) is exercised with real
sockets and the robot's pose checked on the sim.
"""

from __future__ import annotations

import asyncio
import contextlib

import numpy as np
import pytest

from aioadept import Here, MoveToolZ
from aioadept.apps.focus import FocusParams, ufloop_with_stop
from aioadept.apps.paper import init_move
from aioadept.apps.paper import ufloop
from aioadept.errors import FocusError, FocusStopped, StopFailed
from aioadept.bus import Communicator, Responder
from aioadept.bus.messages import encode_event
from aioadept.bus.pubsub import Publisher, Subscriber
from aioadept.client import RobotClient
from aioadept.errors import CommandError
from aioadept.geometry import Pose
from aioadept.protocol import Ack, LineFramer, Status, encode_ack, parse_command
from aioadept.testing.sim import running_sim

pytestmark = pytest.mark.timeout(30)

ANY = "tcp://127.0.0.1:0"


class ScriptedVision:
    """Answers VisionRequests with the next value of a series; a str value is answered as an error."""

    def __init__(self, series):
        self.series = list(series)
        self.requests = 0

    def __call__(self, event_type, rid, attrs):
        i = self.requests
        self.requests += 1
        value = self.series[min(i, len(self.series) - 1)]
        if isinstance(value, str):
            return {"error": value}
        return {"sharpness": float(value), "frame_t": 0.0}


@contextlib.asynccontextmanager
async def cell(handler, *, timeout_s=3.0, time_scale=50.0):
    """A fast sim, a scripted vision Responder, and a connected RobotClient + Communicator."""
    async with contextlib.AsyncExitStack() as stack:
        sim = await stack.enter_async_context(running_sim(time_scale=time_scale))
        responder = await stack.enter_async_context(Responder(ANY, ANY, handler))
        rc = await stack.enter_async_context(RobotClient(sim.host, sim.port))
        comm = await stack.enter_async_context(
            Communicator(responder.peer_request_endpoint, responder.peer_response_endpoint,
                         timeout_s=timeout_s))
        yield rc, comm


def _tool_z_offset_mm(approach, pose):
    """Signed distance from approach to pose along the approach pose's tool z axis."""
    z_axis = approach.to_matrix()[:3, 2]
    return float(np.dot(pose.position_mm - approach.position_mm, z_axis))


async def test_ufloop_stops_after_the_first_fall_and_steps_back_to_the_peak():
    vision = ScriptedVision([10, 20, 30, 25])
    async with cell(vision) as (rc, comm):
        result = await ufloop(rc, comm, 2.0, 50, max_steps=10)
        here = (await rc.cmdexec(Here())).pose
    assert result.sharpness == (10, 20, 30, 25)
    assert result.peak_index == 2 and result.peak_offset_mm == pytest.approx(4.0)
    # Three steps forward, one back: the robot rests 2 steps (4 mm) along tool z from the approach pose.
    assert _tool_z_offset_mm(result.approach_pose, here) == pytest.approx(4.0, abs=0.01)
    assert here.translation_distance_mm(result.inspection_pose) < 0.01
    assert vision.requests == 4


async def test_step_limit_raises_and_retracts_to_the_approach_pose():
    vision = ScriptedVision(range(1, 100))  # sharpness rises forever: no peak
    async with cell(vision) as (rc, comm):
        approach = (await init_move(rc)).pose
        with pytest.raises(FocusError, match="no sharpness peak within 3 steps") as info:
            await ufloop(rc, comm, 2.0, 50, max_steps=3)
        here = (await rc.cmdexec(Here())).pose
    assert info.value.retracted is True
    assert info.value.sharpness == (1, 2, 3, 4)
    assert here.translation_distance_mm(approach) < 0.01


async def test_no_object_error_from_vision_is_a_clear_focus_error_and_the_robot_retracts():
    vision = ScriptedVision([10, 12, "no object found"])
    async with cell(vision) as (rc, comm):
        approach = (await init_move(rc)).pose
        with pytest.raises(FocusError, match="step 2: vision node: no object found") as info:
            await ufloop(rc, comm, 2.0, 50, max_steps=10)
        here = (await rc.cmdexec(Here())).pose
    assert info.value.retracted is True
    assert here.translation_distance_mm(approach) < 0.01


async def test_absent_vision_node_times_out_with_a_clear_error():
    async with running_sim(instant=True) as sim:
        async with RobotClient(sim.host, sim.port) as rc, \
                Communicator("tcp://127.0.0.1:1", "tcp://127.0.0.1:2", timeout_s=0.5) as comm:
            with pytest.raises(FocusError, match="step 0: no answer from the vision node") as info:
                await ufloop(rc, comm, 2.0, 50, max_steps=10, vision_timeout_s=0.5)
            assert info.value.retracted is True


class StopSpy:
    """Wraps a RobotClient's stop() to see when the stop listener called it (the real stop still runs)."""

    def __init__(self, rc):
        self.called = asyncio.Event()
        self._stop = rc.stop
        rc.stop = self

    async def __call__(self, **kw):
        try:
            return await self._stop(**kw)
        finally:
            self.called.set()


async def test_stop_event_on_the_bus_stops_the_robot_and_ufloop_does_not_retract():
    # Run the loop with a concurrent stop listener; a stop event stops the robot wherever the loop is.
    vision = ScriptedVision(range(1, 100))
    async with cell(vision, time_scale=1.0) as (rc, comm), Publisher(ANY, bind=True) as stop_pub, \
            Subscriber(stop_pub.actual_endpoint, bind=False) as sub:
        await init_move(rc)
        spy = StopSpy(rc)

        async def stopper():
            # Re-publish until the listener has acted (ZeroMQ slow joiner), never sleeping for readiness.
            while not spy.called.is_set():
                await stop_pub.send(encode_event("StopRequest", "st0p0001", {}))
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(spy.called.wait(), 0.05)

        task = asyncio.create_task(stopper())
        # Slow steps (10 mm at 1 %, real time: over a second each), so a motion is in progress at the stop.
        params = FocusParams(delta_z_mm=10.0, approach_speed=1, max_steps=5)
        with pytest.raises(FocusStopped) as info:
            await ufloop_with_stop(rc, comm, sub, params, do_init_move=False)
        await task
        before = (await rc.cmdexec(Here())).pose
        after = (await rc.cmdexec(Here())).pose
    assert spy.called.is_set() and info.value.stop_id == "st0p0001"
    assert before.translation_distance_mm(after) < 1e-6, "the robot stays where the stop left it"


async def test_move_tool_z_moves_along_the_tool_axis():
    async with running_sim(instant=True) as sim, RobotClient(sim.host, sim.port) as rc:
        approach = (await init_move(rc)).pose
        pose = (await rc.cmdexec(MoveToolZ(7.5))).pose
    assert _tool_z_offset_mm(approach, pose) == pytest.approx(7.5, abs=0.01)


@contextlib.asynccontextmanager
async def refusing_stop_server():
    """A robot server (real TCP) without the stop extension: it answers ``stop`` with an error ack, holds every
    ``break`` (the motion goes on) and acks the rest at once. Yields (host, port, lines received)."""
    lines: list[bytes] = []
    pose = Pose(480.0, 0.0, 710.0, 0.0, 180.0, 0.0)

    async def serve(reader, writer):
        framer = LineFramer()
        with contextlib.suppress(ConnectionError):
            while data := await reader.read(4096):
                for line in framer.feed(data):
                    lines.append(bytes(line))
                    msg = parse_command(line)
                    if msg.skill == "stop":
                        writer.write(encode_ack(Ack.error(msg.id, -406, "undefined skill stop", 1.0, 1.0, pose)))
                    elif msg.skill != "break":
                        writer.write(encode_ack(Ack(msg.id, Status.DONE, 1.0, 1.0, pose, ())))
        writer.close()

    server = await asyncio.start_server(serve, "127.0.0.1", 0)
    async with server:
        yield "127.0.0.1", server.sockets[0].getsockname()[1], lines


async def test_a_stop_event_whose_stop_fails_raises_stop_failed_not_focus_stopped():
    # A failed stop is an error; the run must not report "stopped".
    vision = ScriptedVision(range(1, 100))
    async with refusing_stop_server() as (host, port, lines), RobotClient(host, port) as rc, \
            Responder(ANY, ANY, vision) as responder, \
            Communicator(responder.peer_request_endpoint, responder.peer_response_endpoint,
                         timeout_s=3.0) as comm, \
            Publisher(ANY, bind=True) as stop_pub, Subscriber(stop_pub.actual_endpoint, bind=False) as sub:

        async def stopper():
            # The first step's break is held (a motion in progress); re-publish (slow joiner) until the stop is sent.
            while not any(line.endswith(b":stop") for line in lines):
                if any(line.endswith(b":break") for line in lines):
                    await stop_pub.send(encode_event("StopRequest", "st0p0002", {}))
                await asyncio.sleep(0.02)

        task = asyncio.create_task(stopper())
        params = FocusParams(delta_z_mm=2.0, approach_speed=10, max_steps=5)
        with pytest.raises(StopFailed) as info:
            await ufloop_with_stop(rc, comm, sub, params, do_init_move=False)
        await task
    assert not isinstance(info.value, FocusStopped)
    assert info.value.stop_id == "st0p0002"
    assert isinstance(info.value.__cause__, CommandError)
    assert "the stop failed" in str(info.value) and "may still be moving" in str(info.value)
    assert lines[-1].endswith(b":stop"), "nothing (no retract) is sent after the stop"
