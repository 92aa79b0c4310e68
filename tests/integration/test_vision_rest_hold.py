"""The virtual camera's pose at a frame time without waiting for the next state sample when the robot is at rest: the sim publishes a sample the moment a motion ends, and the follower holds an at-rest pose that is
at most ``rest_hold_s`` old. A sample in motion, or an old one, still waits (real ZeroMQ, real sim)."""

from __future__ import annotations

import asyncio
import time

import pytest

from aioadept import MoveToolZ
from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import SyncPublisher
from aioadept.client import RobotClient
from aioadept.geometry import Pose, poses_close
from aioadept.testing.sim import running_sim
from aioadept.vision.virtual_camera import RobotStateFollower


def _state(pose: Pose, in_motion: bool) -> bytes:
    return RobotState(t_s=0.0, wall_time_s=time.time(), joints_deg=(0,) * 6, pose=pose,
                      in_motion=in_motion).to_bytes()


def _first_sample(pub: SyncPublisher, follower: RobotStateFollower, pose: Pose, in_motion: bool) -> None:
    t0 = time.time()
    while not follower.history.wait_covering(t0, 0.02):  # slow joiner: publish until one arrives
        pub.publish(ROBOT_STATE_TOPIC, _state(pose, in_motion))  # stamped when sent, as the sim does


@pytest.mark.timeout(20)
def test_at_rest_sample_is_held_without_waiting_and_a_moving_or_old_one_still_waits():
    rest, moving = Pose(x=1.0, z=100.0), Pose(x=5.0, z=100.0)
    with SyncPublisher("tcp://127.0.0.1:0") as pub:
        with RobotStateFollower(pub.actual_endpoint, max_wait_s=1.0, rest_hold_s=0.5) as follower:
            _first_sample(pub, follower, rest, in_motion=False)
            t_frame = time.time() + 0.01  # after the newest sample, within rest_hold_s
            t0 = time.monotonic()
            assert follower.pose_at(t_frame) == rest
            assert time.monotonic() - t0 < 0.8 and follower.rest_holds == 1  # no max_wait_s wait
            # Older than rest_hold_s: the stream may have stalled, so wait for a covering sample as before.
            t0 = time.monotonic()
            assert follower.pose_at(time.time() + 1.0) == rest
            assert time.monotonic() - t0 >= 0.99 and follower.rest_holds == 1
        with RobotStateFollower(pub.actual_endpoint, max_wait_s=1.0, rest_hold_s=0.5) as follower:
            _first_sample(pub, follower, moving, in_motion=True)
            t0 = time.monotonic()
            assert follower.pose_at(time.time() + 0.01) == moving
            assert time.monotonic() - t0 >= 0.99 and follower.rest_holds == 0  # in motion: waited


def test_rest_hold_must_be_finite():
    with pytest.raises(ValueError, match="rest_hold_s"):
        RobotStateFollower("tcp://127.0.0.1:9", rest_hold_s=float("nan"))


@pytest.mark.timeout(20)
async def test_sim_publishes_an_at_rest_sample_when_a_motion_ends():
    # 0.2 Hz: the periodic stream alone would not show the end of any of these moves within the test's 2 s.
    async with running_sim(state_endpoint="tcp://127.0.0.1:0", state_rate_hz=0.2) as sim:
        follower = RobotStateFollower(sim.state_endpoint).start()
        try:
            heard = False
            async with RobotClient(sim.host, sim.port) as robot:
                for _ in range(10):  # slow joiner: the first moves may end before the follower is connected
                    await robot.cmdexec_joined(MoveToolZ(0.5))
                    here = sim.controller.here
                    for _ in range(50):
                        state = follower.last_state
                        if (state is not None and not state.in_motion
                                and poses_close(state.pose, here, tol_mm=1e-6, tol_deg=1e-6)):
                            heard = True
                            break
                        await asyncio.sleep(0.002)
                    if heard:
                        break
            assert heard, "no at-rest sample at the end of a motion"
            assert follower.history.newest_at_rest() is not None
        finally:
            follower.stop()
