"""The virtual camera's guessed pose: a frame rendered ahead from the at-rest sample is kept only
when the sample covering the exposure gives the same pose; otherwise it is rendered again from that pose."""

from __future__ import annotations

import numpy as np

from aioadept.geometry import Pose
from aioadept.vision.sharpness import measure
from aioadept.vision.virtual_camera import PoseHistory, paper_approach_pose, paper_camera, same_pose

APPROACH = paper_approach_pose()


def camera(pose_at, guess):  # noqa: ANN001, ANN202
    # noise_sigma=0: two renders of the same pose are the same image, so the test can compare frames.
    return paper_camera(pose_at, clock=lambda: 100.0, sleep=None, noise_sigma=0.0, pose_guess=guess)


def test_guess_confirmed_by_the_covering_pose_keeps_the_frame_rendered_ahead():
    rest = APPROACH @ Pose(z=20)
    order: list[str] = []
    cam = camera(lambda t: order.append("wait") or rest @ Pose(x=1e-9), lambda t: order.append("guess") or rest)
    f = cam.grab()
    assert order == ["guess", "wait"]  # rendered before the wait, and the wait still happened
    assert (cam.guesses, cam.rerenders) == (1, 0)
    assert np.array_equal(f.image, cam.render(rest))


def test_robot_moved_after_the_at_rest_sample_the_frame_is_rendered_again_from_the_covering_pose():
    before, moved = APPROACH @ Pose(z=0), APPROACH @ Pose(z=20)
    cam = camera(lambda t: moved, lambda t: before)
    f = cam.grab()
    assert (cam.guesses, cam.rerenders) == (1, 1)
    assert np.array_equal(f.image, cam.render(moved)) and not np.array_equal(f.image, cam.render(before))
    assert measure(f.image).sharpness > measure(cam.render(before)).sharpness  # the in-focus pose, not the old one


def test_no_guess_renders_once_from_the_covering_pose():
    pose = APPROACH @ Pose(z=20)
    cam = camera(lambda t: pose, lambda t: None)
    f = cam.grab()
    assert (cam.guesses, cam.rerenders) == (0, 0) and np.array_equal(f.image, cam.render(pose))


def test_same_pose_tolerates_rounding_only():
    p = APPROACH @ Pose(z=20)
    assert same_pose(p, p @ Pose(x=1e-9)) and same_pose(None, None)
    assert not same_pose(p, p @ Pose(x=1e-3)) and not same_pose(p, p @ Pose(roll=1e-3)) and not same_pose(p, None)


def test_follower_guess_only_from_an_at_rest_sample_received_before_t():
    from aioadept.vision.virtual_camera import RobotStateFollower

    f = RobotStateFollower("tcp://127.0.0.1:1", history=PoseHistory())  # not started: the history is fed by hand
    assert f.pose_if_at_rest(10.0) is None  # no sample
    f.history.add(9.0, APPROACH, in_motion=True)
    assert f.pose_if_at_rest(10.0) is None  # moving
    f.history.add(9.5, APPROACH @ Pose(z=2), in_motion=False)
    assert same_pose(f.pose_if_at_rest(10.0), APPROACH @ Pose(z=2))
    assert f.pose_if_at_rest(9.4) is None  # the at-rest sample came after t: no claim about t
