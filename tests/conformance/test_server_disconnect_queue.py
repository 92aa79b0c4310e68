"""A disconnected client's queued commands never run (docs/security.md, "Safety promises"), on every backend.

A client queues a long motion and a second one back, and disconnects once the first has started. The second never
runs: another client, once the arm is at rest, finds it on the first motion's path (J1 between 0 and 150 deg,
never on the way to -150; on a Cobra 100 and -100), and still there a while later. The sim lets the first motion go on to its end; the V+
server brakes it (its second MOVE waits for its turn in the executor, and V+ takes back a motion instruction
another task waits in only with BRAKE; docs/vplus.md, "A client that goes"). Before, the V+ server ran the second
motion: the arm ended at J1 = -150 deg.
"""

from __future__ import annotations

import asyncio
import math

import pytest

from aioadept.geometry import poses_close
from aioadept.protocol import Status


def j1_of(arm, pose) -> float:
    """J1 of a pose on a J1-only path from home: J1 turns the flange about the base axis, on both families."""
    home = arm.home_pose
    turn = math.degrees(math.atan2(pose.y, pose.x) - math.atan2(home.y, home.x))
    return math.remainder(turn, 360.0)


@pytest.mark.timeout(90)
async def test_a_client_that_goes_with_a_second_motion_queued_never_gets_it_run(server, arm):
    first, second = arm.j1(150), arm.j1(-150)      # J1 0 -> 150 deg at 20 %: a few seconds; back: must never run
    a = await server.connect()
    await a.send(f"kq000001:set_speed:{arm.speed(20)}", f"kq000002:move_joints:{arm.wire(first)}",
                 f"kq000003:move_joints:{arm.wire(second)}")
    speed, move = await a.acks(2, timeout=30)
    assert speed.status is Status.DONE and move.status is Status.DONE, (speed, move)
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
    # J1 turns the flange about the base (and the tool's roll with it): the rest pose is on the first motion's path
    j1 = j1_of(arm, poses[0])
    assert -0.5 <= j1 <= first[0] + 0.5, (j1, poses)
    assert poses_close(poses[0], arm.pose(arm.with_joint(0, j1)), tol_mm=0.5, tol_deg=0.5), poses
    if server.backend == "python":
        assert poses_close(poses[0], arm.pose(first), tol_mm=0.5, tol_deg=0.5), poses
