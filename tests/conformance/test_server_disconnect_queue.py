"""A disconnected client's queued commands never run (docs/security.md, "Safety promises"), on every backend.

A client queues a long motion and a second one back, and disconnects once the first has started. The second never
runs: another client, once the arm is at rest, finds it on the first motion's path (J1 between 0 and 150 deg,
never on the way to -150), and still there a while later. The sim lets the first motion go on to its end; the V+
server brakes it (its second MOVE waits for its turn in the executor, and V+ takes back a motion instruction
another task waits in only with BRAKE; docs/vplus.md, "A client that goes"). Before, the V+ server ran the second
motion: the arm ended at J1 = -150 deg.
"""

from __future__ import annotations

import asyncio

import pytest

from aioadept.protocol import Status

FIRST = "move_joints:150,-90,180,0,90,0"     # J1 0 -> 150 deg at 20 %: a few seconds
SECOND = "move_joints:-150,-90,180,0,90,0"   # back through 0 to -150: must never run
AT_FIRST = (-415.692, 240.0, 710.0)          # the flange at FIRST's joints (home is 480, 0, 710)


@pytest.mark.timeout(90)
async def test_a_client_that_goes_with_a_second_motion_queued_never_gets_it_run(server):
    a = await server.connect()
    await a.send("kq000001:set_speed:20", f"kq000002:{FIRST}", f"kq000003:{SECOND}")
    speed, first = await a.acks(2, timeout=30)
    assert speed.status is Status.DONE and first.status is Status.DONE, (speed, first)
    await asyncio.sleep(0.2)              # the first motion runs, the second waits for its turn
    await a.close()
    b = await server.connect()
    await b.send("kr000001:break")        # done once the arm is at rest: the first motion's end
    assert (await b.ack(timeout=60)).status is Status.DONE
    poses = []
    for n in range(2):
        await b.send(f"kr00000{n + 2}:here")
        here = await b.ack()
        assert here.status is Status.DONE
        poses.append(here.pose)
        await asyncio.sleep(1.0)          # and nothing starts later either
    await b.close()
    assert poses[0] == poses[1], poses
    # J1 turns the flange about the base and the tool's roll with it (roll = -J1 here): on the first motion's path
    assert -150.5 <= poses[0].roll <= 0.5 and poses[0].y >= -0.5 and poses[0].z == pytest.approx(710.0), poses
    if server.backend == "python":
        assert (poses[0].x, poses[0].y, poses[0].z) == pytest.approx(AT_FIRST, abs=0.5), poses
