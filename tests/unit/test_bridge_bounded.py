"""The bridge's memory is bounded: a flood of queries from thousands of application names while
the writer is busy leaves at most MAX_QUEUED_TOTAL batches (and as many per-application counters) in the bridge,
refuses the rest ``full`` (which BridgeClient raises as TooManyPending), and a stop still goes through at once.

No Zenoh: the queries are handed in from a thread, as Zenoh's callback thread hands them; the controller is a
ScriptedServer whose motion holds the writer.
"""

from __future__ import annotations

import asyncio
import threading
import time
from dataclasses import dataclass, field

import pytest

from aioadept.bridge.node import Bridge
from aioadept.bridge.wire import MAX_QUEUED_TOTAL, BridgeFailure, parse_failure
from aioadept.client import RobotClient
from aioadept.protocol import SkillCall
from aioadept.testing import Reply, ScriptedServer

FLOOD = 20_000


@dataclass
class _Bytes:
    data: bytes

    def to_bytes(self) -> bytes:
        return self.data


@dataclass
class ThreadQuery:
    """What the bridge uses of a ``zenoh.Query``; answers may come from any thread, as Zenoh allows."""

    payload: _Bytes
    attachment: _Bytes
    answers: list = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def reply(self, key: str, payload: bytes) -> None:
        with self.lock:
            self.answers.append(("ok", payload))

    def reply_err(self, payload: bytes) -> None:
        with self.lock:
            self.answers.append(("err", payload))

    def drop(self) -> None:
        pass


def q(app: str, line: str) -> ThreadQuery:
    return ThreadQuery(_Bytes(f"{line}\r\n".encode()), _Bytes(app.encode()))


async def answered(query: ThreadQuery, timeout_s: float = 5.0):
    deadline = time.monotonic() + timeout_s
    while not query.answers:
        assert time.monotonic() < deadline, "no answer"
        await asyncio.sleep(0.001)
    return query.answers[0]


@pytest.mark.timeout(60)
async def test_a_flood_from_many_application_names_stays_bounded_and_a_stop_goes_through():
    server = ScriptedServer({"move_joints": Reply(delay_s=30.0)})
    robot = RobotClient(connector=server.connector(), stop_port=None)
    bridge = Bridge(robot)
    bridge._loop = asyncio.get_running_loop()
    pump = asyncio.create_task(bridge._pump())
    try:
        moving = q("mover", "00000001:move_joints:0,0,0,0,0,0")
        bridge._on_query_thread(moving)
        await asyncio.sleep(0.1)                    # the writer is busy with it
        flood = [q(f"app{n}", f"{n + 1:08x}:here") for n in range(FLOOD)]

        def zenoh_thread() -> None:
            for query in flood:
                bridge._on_query_thread(query)

        await asyncio.to_thread(zenoh_thread)
        deadline = time.monotonic() + 20
        while sum(bool(f.answers) for f in flood) + len(bridge._jobs) < FLOOD:
            assert time.monotonic() < deadline
            await asyncio.sleep(0.01)
        queued_jobs, queued_apps = len(bridge._jobs), len(bridge._queued)
        refused = [parse_failure(f.answers[0][1]) for f in flood if f.answers]
        waiting = [f for f in flood if not f.answers]
        t0 = time.monotonic()
        stop = q("real", "0000beef:stop")
        bridge._on_query_thread(stop)
        kind, _ = await answered(stop)
        stop_s = time.monotonic() - t0
        aborted = [parse_failure((await answered(f))[1]).kind for f in waiting]
    finally:
        pump.cancel()
        await robot.close()
    assert queued_jobs <= MAX_QUEUED_TOTAL and queued_apps <= MAX_QUEUED_TOTAL
    assert len(refused) == FLOOD - queued_jobs and {f.kind for f in refused} == {"full"}
    assert "not sent" in refused[0].text
    assert kind == "ok" and stop_s < 1.0           # generous: the figure is bench_bridge's
    assert len(waiting) == queued_jobs and set(aborted) <= {"aborted"}
    assert bridge.stats.full == len(refused)
    assert [line.split(b":")[1] for line in server.lines()] == [b"move_joints", b"stop"]   # nothing else sent


def test_the_client_raises_a_full_bridge_as_too_many_pending():
    from aioadept.bridge.client import _error_of
    from aioadept.errors import TooManyPending

    exc = _error_of(BridgeFailure("full", "the bridge already holds 256 batches of all applications waiting; "
                                          "not sent"), (SkillCall("here"),))
    assert isinstance(exc, TooManyPending) and exc.limit == MAX_QUEUED_TOTAL
    assert str(exc).startswith("the robot bridge is full: ")
