"""The generated Viper s850 URDF: an independent URDF library (yourdfpy) computes the same flange as our forward
kinematics, and the per-link transforms that run.mcap records compose to it too."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.robots import viper_s850 as kin
from aioadept.robots.viper_s850_urdf import FLANGE_LINK, JOINTS, link_transforms, quaternion_xyzw, urdf

yourdfpy = pytest.importorskip("yourdfpy")

_LIM = kin.VIPER_S850_LIMITS
joints = st.tuples(*(st.floats(lo, hi, allow_nan=False) for lo, hi in zip(_LIM.min_deg, _LIM.max_deg, strict=True)))


@pytest.fixture(scope="module")
def model():
    return yourdfpy.URDF.load(io.BytesIO(urdf().encode()), load_meshes=False, build_collision_scene_graph=False)


def test_the_urdf_has_six_revolute_joints_with_our_limits(model):
    assert model.robot.name == "viper_s850"
    assert [j.name for j in model.robot.joints] == [j.name for j in JOINTS]
    for i, j in enumerate(model.robot.joints):
        assert j.type == "revolute"
        assert (j.limit.lower, j.limit.upper) == pytest.approx(
            (math.radians(_LIM.min_deg[i]), math.radians(_LIM.max_deg[i])))


@settings(max_examples=300, deadline=None)
@given(q=joints)
def test_yourdfpy_forward_kinematics_matches_ours_within_a_micrometre(model, q):
    model.update_cfg(np.radians(q))
    theirs = model.get_transform(FLANGE_LINK, "base_link")
    ours = kin.flange_matrix(q)
    np.testing.assert_allclose(theirs[:3, 3], ours[:3, 3] / 1000.0, rtol=0, atol=1e-6)
    np.testing.assert_allclose(theirs[:3, :3], ours[:3, :3], rtol=0, atol=1e-7)  # yourdfpy rounds to ~1e-9


@settings(max_examples=300, deadline=None)
@given(q=joints)
def test_the_recorded_link_transforms_compose_to_our_flange(q):
    m = np.eye(4)
    for _parent, _child, t, r in link_transforms(q):
        step = np.eye(4)
        step[:3, :3], step[:3, 3] = r, t
        m = m @ step
    ours = kin.flange_matrix(q)
    np.testing.assert_allclose(m[:3, 3], ours[:3, 3] / 1000.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(m[:3, :3], ours[:3, :3], rtol=0, atol=1e-12)


@settings(max_examples=300, deadline=None)
@given(q=joints)
def test_the_quaternion_is_the_rotation(q):
    r = kin.flange_matrix(q)[:3, :3]
    x, y, z, w = quaternion_xyzw(r)
    back = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    np.testing.assert_allclose(back, r, atol=1e-12)


def test_home_puts_the_flange_where_the_ack_in_facts_says(model):
    model.update_cfg(np.radians(kin.HOME_JOINTS_DEG))
    np.testing.assert_allclose(model.get_transform(FLANGE_LINK, "base_link")[:3, 3], [0.48, 0.0, 0.71], atol=1e-9)


def test_link_transforms_refuses_a_wrong_joint_count():
    with pytest.raises(ValueError, match="expected 6"):
        link_transforms([0.0] * 5)
