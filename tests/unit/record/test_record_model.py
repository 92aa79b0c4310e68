"""The arm the viewer draws is the arm of the kinematics module: same flange, same wrist centre."""

from __future__ import annotations

import numpy as np
import pytest

from aioadept.record.model import chain_points_mm, joints_from_pose
from aioadept.robots import viper_s850 as kin

pytestmark = pytest.mark.timeout(30)

JOINTS = [(0, -90, 180, 0, 90, 0), (-90, -30, 210, -90, 90, 1.5), (30, -60, 150, 20, 45, -30)]


@pytest.mark.parametrize("joints", JOINTS)
def test_chain_ends_at_the_flange_and_passes_the_wrist_centre(joints):
    pts = chain_points_mm(joints)
    m = kin.flange_matrix(joints)
    assert pts.shape == (7, 3)
    np.testing.assert_allclose(pts[0], 0.0)
    np.testing.assert_allclose(pts[-1], m[:3, 3], atol=1e-9)
    # the wrist centre is d6 behind the flange along the tool z axis
    np.testing.assert_allclose(pts[-2], m[:3, 3] - kin.D6_MM * m[:3, 2], atol=1e-9)
    # link lengths are the robot's
    assert np.linalg.norm(pts[3] - pts[2]) == pytest.approx(kin.A2_MM)
    assert np.linalg.norm(pts[5] - pts[3]) == pytest.approx(np.hypot(kin.A3_MM, kin.D4_MM))


def test_joints_from_an_acked_pose_reproduce_the_pose():
    joints = JOINTS[1]
    pose = kin.forward(joints)
    back = joints_from_pose(pose, kin.HOME_JOINTS_DEG)
    assert back is not None
    np.testing.assert_allclose(kin.forward(back).position_mm, pose.position_mm, atol=1e-6)


def test_an_unreachable_pose_gives_none_not_an_error():
    from aioadept.geometry import Pose

    assert joints_from_pose(Pose(5000, 0, 0, 0, 180, 0)) is None


def test_wrong_joint_count_is_a_clear_error():
    with pytest.raises(ValueError, match="6 values"):
        chain_points_mm([0, 0, 0])


def test_a_cobras_chain_is_its_own_and_ends_at_its_flange():
    from aioadept.record.model import chain_labels
    from aioadept.robots import model

    cobra = model("cobra-s600")
    q = (20.0, 60.0, 120.0, 30.0)
    pts = chain_points_mm(q, cobra)
    assert chain_labels(cobra) == ["base", "joint_1", "joint_2", "joint_3", "flange"]
    np.testing.assert_allclose(pts[-1], cobra.flange_matrix(q)[:3, 3], atol=1e-9)
    # the quill hangs straight down by J3 (mm) from the end of the second link, at the height of the first
    np.testing.assert_allclose(pts[-2] - pts[-1], (0.0, 0.0, q[2]), atol=1e-9)
    assert pts[-2][2] == pytest.approx(cobra.d1) and np.linalg.norm(pts[2] - pts[1]) == pytest.approx(cobra.a1)
    back = joints_from_pose(cobra.forward(q), cobra.home_deg, cobra)
    assert back == pytest.approx(q, abs=1e-6)
    with pytest.raises(ValueError, match="4 values"):
        chain_points_mm(kin.HOME_JOINTS_DEG, cobra)


def test_a_runs_model_is_its_cell_files():
    from aioadept.record.model import run_model

    assert run_model({"parameters": {"cell": {"robot": {"model": "cobra-s800"}}}}).name == "cobra-s800"
    assert run_model({"parameters": {"app": "focus"}}).name == run_model(None).name == "viper-s850"  # older runs
