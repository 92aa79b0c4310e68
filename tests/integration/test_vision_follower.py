"""RobotStateFollower over real ZeroMQ: samples placed at their own time on the local clock (their wall time on one
machine), a frame waits for the sample covering its time."""

from __future__ import annotations

import threading
import time

import pytest

from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import SyncPublisher
from aioadept.geometry import Pose
from aioadept.vision.virtual_camera import RobotStateFollower


def _state(pose: Pose) -> bytes:
    return RobotState(t_s=0.0, wall_time_s=time.time(), joints_deg=(0,) * 6, pose=pose).to_bytes()


@pytest.mark.timeout(20)
def test_follower_interpolates_at_frame_time_and_waits_for_the_covering_sample():
    a, b = Pose(x=0.0, z=100.0), Pose(x=10.0, z=100.0)
    with SyncPublisher("tcp://127.0.0.1:0") as pub:
        follower = RobotStateFollower(pub.actual_endpoint, max_wait_s=2.0).start()
        try:
            # Slow joiner: publish until the follower has a sample (a retry loop, each round waits on it).
            t0 = time.time()
            while not follower.history.wait_covering(t0, 0.02):
                pub.publish(ROBOT_STATE_TOPIC, _state(a))
            assert follower.received >= 1 and follower.pose_at(t0 - 10) == a
            # A frame at t_frame: the pose there depends on a sample that arrives later; pose_at waits for it.
            t_frame = time.time() + 0.05
            # Built when sent, as the sim stamps a sample when it takes it.
            timer = threading.Timer(0.1, lambda: pub.publish(ROBOT_STATE_TOPIC, _state(b)))
            timer.start()
            try:
                pose = follower.pose_at(t_frame)
                waited_until = time.time()
            finally:
                timer.join()
            assert waited_until >= t_frame
            assert 0.0 < pose.x < 10.0  # between the last sample of a and the first of b
            # A stalled stream: after max_wait_s the last pose, not a hang.
            follower.max_wait_s = 0.05
            t1 = time.monotonic()
            assert follower.pose_at(time.time() + 10).x == pytest.approx(10.0)
            assert time.monotonic() - t1 < 1.0
        finally:
            follower.stop()
    assert not any(t.name.startswith("robot-state:") for t in threading.enumerate())


@pytest.mark.timeout(10)
def test_follower_without_samples_answers_none_at_once():
    with RobotStateFollower("tcp://127.0.0.1:9", max_wait_s=5.0) as follower:
        t0 = time.monotonic()
        assert follower.pose_at(time.time()) is None
        assert time.monotonic() - t0 < 1.0


@pytest.mark.timeout(20)
def test_a_sample_delayed_on_its_way_is_placed_at_its_own_time():
    """A sample that arrives late (a busy process) keeps its own time (one machine, one clock: its wall
    time), so the pose the camera shows does not lag the robot by that sample's delay (0.2 mm at 200 mm/s per
    ms); a sender whose clock runs ahead (a sample received before it was taken) is shifted back by that lead."""
    a = Pose(x=0.0, z=100.0)
    with SyncPublisher("tcp://127.0.0.1:0") as pub:
        follower = RobotStateFollower(pub.actual_endpoint, max_wait_s=2.0).start()
        try:
            t0 = time.time()
            while not follower.history.wait_covering(t0, 0.02):
                pub.publish(ROBOT_STATE_TOPIC, _state(a))
            fastest = follower.min_delay_s
            assert fastest is not None and 0.0 <= fastest < 0.05
            time.sleep(0.3)
            taken = time.time() - 0.1  # a sample taken 100 ms ago (after the last one), sent only now
            pub.publish(ROBOT_STATE_TOPIC, RobotState(t_s=0.0, wall_time_s=taken, joints_deg=(0,) * 6,
                                                      pose=Pose(x=5.0, z=100.0)).to_bytes())
            n = follower.received
            deadline = time.monotonic() + 5.0
            while follower.received == n and time.monotonic() < deadline:
                time.sleep(0.005)
            stamp = follower.history.newest_t()
            assert stamp == pytest.approx(taken, abs=1e-6)  # not its receipt time
            ahead = time.time() + 1.0  # a sender 1 s ahead of our clock
            pub.publish(ROBOT_STATE_TOPIC, RobotState(t_s=0.0, wall_time_s=ahead, joints_deg=(0,) * 6,
                                                      pose=Pose(x=6.0, z=100.0)).to_bytes())
            n = follower.received
            deadline = time.monotonic() + 5.0
            while follower.received == n and time.monotonic() < deadline:
                time.sleep(0.005)
            assert follower.min_delay_s < -0.9
            assert follower.history.newest_t() == pytest.approx(ahead + follower.min_delay_s, abs=1e-6)
            assert follower.history.newest_t() <= time.time()
        finally:
            follower.stop()
