"""The simulated server's collaborators, each alone: the state publisher (a recording publisher, samples given to it)
and the stop paths (the choice of a connection to evict, the line parse; the stop port and the reserved stop path
served over a real connection on 127.0.0.1 for a host that records what reaches the controller)."""

from __future__ import annotations

import asyncio
import logging
from types import SimpleNamespace

import pytest

from aioadept.errors import BusError
from aioadept.geometry import NULL
from aioadept.ports import free_port
from aioadept.protocol import Ack, ErrorCode, Status, encode_ack, parse_ack
from aioadept.sim.statepub import MOTION_END_SAMPLE_FAILED, SAMPLE_FAILED, StatePublisher
from aioadept.sim.stoppaths import StopPaths, parse_line, probe_to_evict


# ------------------------------------------------------------------------------------------ state publisher
class Sample:
    def __init__(self, n: int, in_motion: bool = False) -> None:
        self.n, self.in_motion = n, in_motion

    def to_bytes(self) -> bytes:
        return b"%d" % self.n


class Recorder:
    def __init__(self) -> None:
        self.sent: list[tuple[bytes, bytes]] = []
        self.refuse = False

    def publish_nowait(self, topic: bytes, payload: bytes) -> None:
        if self.refuse:
            raise BusError("socket full")
        self.sent.append((topic, payload))


async def until(condition, timeout_s: float = 5.0) -> None:
    async with asyncio.timeout(timeout_s):
        while not condition():
            await asyncio.sleep(0.001)


@pytest.mark.timeout(10)
async def test_the_stream_publishes_samples_at_its_rate_and_drops_unsendable_ones_logging_once(caplog):
    pub, counter, failures = Recorder(), iter(range(10**6)), []
    state = StatePublisher(pub, lambda: (Sample(next(counter)), Sample(-1)), 200.0,
                           failed=lambda kind, exc: failures.append(kind))
    caplog.set_level(logging.WARNING, logger="aioadept.sim.statepub")
    state.start()
    await until(lambda: len(pub.sent) >= 6)
    assert {t for t, _ in pub.sent} == {b"robot.state", b"world.state"}
    pub.refuse = True
    await until(lambda: state.failures.dropped >= 2)
    pub.refuse = False
    n = len(pub.sent)
    await until(lambda: len(pub.sent) > n)
    await state.stop()
    kept = len(pub.sent)
    await asyncio.sleep(0.03)
    assert len(pub.sent) == kept and failures == []  # stopped, and a refused send is no failure of the stream
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 2 and "not sent (BusError: socket full)" in said[0] and "dropped samples" in said[1]


@pytest.mark.timeout(10)
async def test_a_sample_that_cannot_be_computed_ends_the_stream_and_is_reported():
    pub, failures = Recorder(), []

    def broken():
        raise ZeroDivisionError("model")

    state = StatePublisher(pub, broken, 200.0, failed=lambda kind, exc: failures.append((kind, type(exc))))
    await state.run()  # returns at the first failed sample
    state.publish_now()
    assert failures == [(SAMPLE_FAILED, ZeroDivisionError), (MOTION_END_SAMPLE_FAILED, ZeroDivisionError)]
    assert pub.sent == []


@pytest.mark.timeout(10)
async def test_halted_it_stops_and_the_injected_fault_fails_only_samples_of_a_moving_arm():
    pub = Recorder()
    state = StatePublisher(pub, lambda: (Sample(1), None), 200.0, failed=lambda *a: None, send_fault=True)
    state.send(Sample(1, in_motion=False), None)
    with pytest.raises(BusError, match="injected"):
        state.send(Sample(2, in_motion=True), None)
    assert pub.sent == [(b"robot.state", b"1")]
    state.halt()
    await state.run()  # returns at once
    assert len(pub.sent) == 1


@pytest.mark.timeout(10)
async def test_after_a_death_it_shows_the_arm_until_at_rest_and_two_samples_more():
    pub, asked = Recorder(), []

    def in_motion() -> bool:
        asked.append(1)
        return len(asked) <= 3

    state = StatePublisher(pub, lambda: (Sample(7), None), 500.0, failed=lambda *a: None)
    state.start()
    await until(lambda: len(pub.sent) >= 1)
    await state.show_rest(in_motion, wait_s=5.0)
    assert len(asked) == 5  # three samples in motion, then the first two at rest
    n = len(pub.sent)
    await asyncio.sleep(0.02)
    assert len(pub.sent) == n  # the periodic samples have ended too
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    await state.show_rest(lambda: True, wait_s=0.05)  # an arm that never comes to rest: at most wait_s
    assert loop.time() - t0 < 1.0 and len(pub.sent) > n


# ------------------------------------------------------------------------------------------------ stop paths
def conn(limited: bool, stopped: bool = False):
    return SimpleNamespace(limited=limited, stopped=stopped)


def test_evicted_is_the_oldest_stop_path_connection_without_a_stop_and_only_when_full():
    a, b, c, client = conn(True, stopped=True), conn(True), conn(True), conn(False)
    assert probe_to_evict([client, a, b, c], 4) is None
    assert probe_to_evict([client, a, b, c], 3) is b
    assert probe_to_evict([a, conn(True, True)], 2) is None  # every one carries a stop: nobody is evicted


def test_a_line_is_a_command_or_nothing():
    assert parse_line(b"00000001:stop").skill == "stop"
    assert parse_line(b"not a command") is None and parse_line(object()) is None


class Host:
    """A server as the stop paths see it: records what reaches the controller, acks stops at once."""

    def __init__(self) -> None:
        self.handled: list[str] = []
        self.busy: set[int] = set()

    def now(self) -> float:
        return 1.0

    def handle(self, item, c, now) -> None:
        self.handled.append(getattr(item, "skill", "?"))
        c.writer.write(encode_ack(Ack(item.id, Status.DONE, now, now, NULL)))
        c.stop_ids.discard(item.id)

    def reschedule(self) -> None:
        pass

    def pending(self, c) -> bool:
        return False

    def settled(self, c) -> bool:
        return not c.stop_ids

    def refusal(self, text: str) -> bytes:
        return encode_ack(Ack.error("00000000", ErrorCode.SERVER_BUSY, text, 1.0, 1.0, NULL))

    def here(self):
        return NULL


async def _serve_one(kind: str, lines: list[bytes], window_s: float) -> tuple[Host, list]:
    """Serve one connection on stop path ``kind`` ("port" or "probe"), send ``lines``; return the host and the
    acks the peer read until the server closed the connection."""
    host = Host()
    paths = StopPaths(host, window_s)

    async def serve(reader, writer):
        c = SimpleNamespace(writer=writer, stopped=False, stop_ids=set(), messages=0, idle=None, limited=True)
        await getattr(paths, f"serve_{kind}")(c, reader, writer)
        writer.close()

    port = free_port("127.0.0.1")
    server = await asyncio.start_server(serve, "127.0.0.1", port)
    try:
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        writer.write(b"".join(line + b"\r\n" for line in lines))
        data = await reader.read()  # until the server closes
        writer.close()
    finally:
        server.close()
        await server.wait_closed()
    return host, [parse_ack(line) for line in data.splitlines()]


@pytest.mark.timeout(10)
async def test_the_stop_port_serves_stop_here_hello_only_and_closes_after_its_window():
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    host, acks = await _serve_one("port", [b"00000001:stop", b"00000002:move_to:1,2,3,0,180,0", b"00000003:here"],
                                  0.2)
    assert host.handled == ["stop", "here"]
    assert [(a.id, a.status.value) for a in acks] == [("00000001", "done"), ("00000002", "error"),
                                                      ("00000003", "done")]
    assert acks[1].error_code == ErrorCode.UNKNOWN_SKILL
    assert 0.15 < loop.time() - t0 < 2.0


@pytest.mark.timeout(10)
async def test_the_reserved_stop_path_runs_stops_and_refuses_anything_else():
    host, acks = await _serve_one("probe", [b"00000001:stop", b"00000002:here"], 5.0)
    assert host.handled == ["stop"]
    assert [(a.id, a.status.value) for a in acks] == [("00000001", "done"), ("00000000", "error")]
    assert acks[1].error_code == ErrorCode.SERVER_BUSY
    host, acks = await _serve_one("probe", [b"00000001:stop"], 0.1)  # only stops: acked, no refusal at the end
    assert host.handled == ["stop"] and [a.id for a in acks] == ["00000001"]
