"""Pose, Adept TRANS (Z-Y-Z) conversions and composition, move_rel_world / move_rel_tool targets."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.geometry import (
    NULL, Pose, decompose, inverse_transform, pose_error, poses_close, rel_tool, rel_world, trans,
)

coord = st.floats(-1000, 1000, allow_nan=False)
angle = st.floats(-180, 180, allow_nan=False)
# Keep pitch off the singularities, where yaw is not defined and decomposition reports yaw = 0.
pitch = st.floats(1, 179, allow_nan=False)
poses = st.builds(Pose, coord, coord, coord, angle, pitch, angle)


def test_trans_is_rz_ry_rz():
    m = trans(0, 0, 0, 90, 90, 0)
    # Rz(90) Ry(90): column 0 is R ex = Rz(90) (0, 0, -1) = (0, 0, -1); column 2 is Rz(90) (1, 0, 0) = (0, 1, 0).
    np.testing.assert_allclose(m[:3, 0], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(m[:3, 2], [0, 1, 0], atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(poses)
def test_trans_decompose_round_trip(p):
    q = decompose(p.to_matrix())
    assert q.as_tuple() == pytest.approx(p.as_tuple(), abs=1e-7)


@settings(max_examples=200, deadline=None)
@given(poses, poses)
def test_compose_matches_matrix_product_and_inverse(a, b):
    c = a @ b
    np.testing.assert_allclose(c.to_matrix(), a.to_matrix() @ b.to_matrix(), atol=1e-6)
    assert poses_close(a.inverse() @ c, b, tol_mm=1e-6, tol_deg=1e-6)
    np.testing.assert_allclose(inverse_transform(a.to_matrix()) @ a.to_matrix(), np.eye(4), atol=1e-9)


def test_decompose_singular_pitch_puts_yaw_in_roll():
    p = decompose(trans(1, 2, 3, 30, 180, 10))
    assert p.yaw == 0.0 and p.pitch == pytest.approx(180)
    assert poses_close(p, Pose(1, 2, 3, 30, 180, 10), tol_deg=1e-9)


def test_rel_world_is_component_wise_angles_included():
    p = Pose(-80, -481, 112.5, 180, 90, 180)
    assert rel_world(p, (10, -20, 5, 0, -5, 2)) == Pose(-70, -501, 117.5, 180, 85, 182)


def test_rel_tool_hand_computed_tool_down():
    # Tool pointing down (Ry(180)): tool z is world -z, tool x is world -x, tool y is world y.
    home = Pose(480, 0, 710, 0, 180, 0)
    t = rel_tool(home, (10, 20, 30, 0, 0, 0))
    assert poses_close(t, Pose(470, 20, 680, 0, 180, 0), tol_mm=1e-9, tol_deg=1e-9)


def test_rel_tool_hand_computed_horizontal_tool():
    # The paper's approach orientation (180, 90, 180): tool z along world -x... compute by hand:
    # Rz(180) Ry(90) Rz(180): z axis = Rz(180) (1, 0, 0) = (-1, 0, 0); x axis = Rz(180) Ry(90) (-1, 0, 0) =
    # Rz(180) (0, 0, 1) = (0, 0, 1); y axis = Rz(180) Ry(90) (0, -1, 0) = (0, 1, 0).
    p = Pose(-80, -481, 112.5, 180, 90, 180)
    t = rel_tool(p, (40, -25, 185, 0, 0, 0))
    assert (t.x, t.y, t.z) == pytest.approx((-80 - 185, -481 - 25, 112.5 + 40))
    assert poses_close(t, Pose(-265, -506, 152.5, 180, 90, 180), tol_mm=1e-9, tol_deg=1e-9)


def test_rel_tool_rotation_composes_in_tool_frame():
    p = Pose(0, 0, 0, 0, 180, 0)
    t = rel_tool(p, (0, 0, 0, 0, 0, 90))
    # The tool x axis starts at world -x. Rotating 90 deg about the tool's z (pointing down) is -90 deg about
    # world z, which takes -x to +y.
    np.testing.assert_allclose(t.to_matrix()[:3, 0], [0, 1, 0], atol=1e-12)


def test_pose_error_measures_distance_and_angle():
    d, a = pose_error(Pose(0, 0, 0, 0, 0, 0), Pose(3, 4, 0, 0, 30, 0))
    assert d == pytest.approx(5) and a == pytest.approx(30)
    assert not poses_close(NULL, Pose(0, 0, 0.01))
    assert math.isclose(pose_error(NULL, NULL)[1], 0.0, abs_tol=1e-12)
