"""A client with a long queue of commands cannot hold off another client's stop, on every backend.

The V+ server reads all its clients through one READ on one LUN: when its command ring was full it stopped
reading, and a stop from anybody waited until the executor had worked through enough of the queue (measured
before the fix: 2.7 s with 81 short moves queued, about 15 s here). Every line still gets exactly one ack.
"""

from __future__ import annotations

import asyncio

import pytest

from aioadept.geometry import poses_close
from aioadept.protocol import ErrorCode, Status

PAIRS = 100  # 201 lines: far beyond the V+ server's command ring
MAX_QUEUED = 64  # per connection: aioadept sim --max-queued (default), rs.maxq in vplus/rserver.V2


@pytest.mark.timeout(150)
async def test_a_stop_is_read_at_once_while_another_client_has_a_long_queue(server, arm):
    a = await server.connect()
    b = await server.connect()
    lines = [f"kk000000:set_speed:{arm.speed(10)}"]
    for i in range(1, PAIRS + 1):
        j1 = 60 if i % 2 else 0  # J1 by 60 deg at 10 %: seconds per move
        lines += [f"km{i:06d}:move_joints:{arm.j1_wire(j1)}", f"kb{i:06d}:break"]
    await a.send(*lines)
    got: dict[str, object] = {}
    first_move = asyncio.Event()

    async def collect() -> None:  # A's acks by ID: refusals (-530) may be written ahead of queued acks
        while len(got) < len(lines):
            ack = await a.ack(60)
            assert ack.id not in got, f"two acks for {ack.id}"
            got[ack.id] = ack
            if ack.id == "km000001":
                first_move.set()

    collector = asyncio.create_task(collect())
    async with asyncio.timeout(30):
        await first_move.wait()
    assert got["kk000000"].status is Status.DONE and got["km000001"].status is Status.DONE
    await asyncio.sleep(0.5)  # the arm is moving; the first break waits
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    await b.send("kz000001:stop")
    stop = await b.ack(60)
    waited = loop.time() - t0
    assert (stop.id, stop.status) == ("kz000001", Status.DONE)
    assert waited < 5.0, f"the stop was acked {waited:.1f} s after it was sent: it waited behind A's queue"
    # Every line of A gets exactly one ack: done before the stop, aborted by it, or refused (-530, too many
    # queued); none is lost, none runs after the stop.
    await asyncio.wait_for(collector, 60)
    assert sorted(got) == sorted(ln[:8] for ln in lines)
    for x in got.values():
        assert x.status in (Status.DONE, Status.ABORTED, Status.ERROR), x
        if x.status is Status.ERROR:
            assert x.error_code == ErrorCode.SERVER_BUSY, x
    # Both servers admit at most 64 queued commands per connection (the sim: --max-queued, as the V+ server's
    # rs.maxq), so what a client can pipeline is the same against the sim and the controller; the refused lines
    # are the last ones. Admitted beyond the 64: the one running, and those done meanwhile (a command done frees its
    # place; on a loaded machine the server reads A's 201 lines over long enough for a few short ones to finish).
    order = [ln[:8] for ln in lines]
    busy = [i for i, cid in enumerate(order) if got[cid].status is Status.ERROR]
    done = sum(1 for x in got.values() if x.status is Status.DONE)
    assert len(lines) - len(busy) <= MAX_QUEUED + done + 1, (len(busy), done)
    assert busy == list(range(busy[0], len(lines)))
    await b.send("kz000002:here")
    at_rest = (await b.ack()).pose
    await asyncio.sleep(1.0)
    await b.send("kz000003:here")
    assert poses_close((await b.ack()).pose, at_rest, tol_mm=0.01, tol_deg=0.01), "nothing ran after the stop"
    await a.close()
    await b.close()
