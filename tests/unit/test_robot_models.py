"""Every robot model of the registry, checked the same way: forward/inverse round trips over random reachable poses
in every configuration, limits and impossible poses refused with V+'s errors, and the model's URDF (through an
independent URDF library) computing the same flange as our forward kinematics."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from aioadept.errors import RobotError
from aioadept.geometry import NULL, Pose, decompose
from aioadept.protocol import ErrorCode
from aioadept.robots import DEFAULT_MODEL, MODELS, all_solutions, model
from aioadept.robots.base import ConfigRequest
from aioadept.robots.urdf import FLANGE_LINK, link_transforms, urdf

NAMES = sorted(MODELS)
N_POSES = 10_000
RNG_SEED = 20260


def _flags(m, q: np.ndarray) -> np.ndarray:
    """(N, 3) configuration flags of joint vectors, from the definitions in docs/sim.md (not the model's code):
    Viper: sign of the wrist centre's distance in front of J1, of -cos(J3 - beta), of sin(J5); SCARA: sign of
    sin(J2) (RIGHTY +1)."""
    r = np.radians(q)
    if m.family == "scara":
        return np.stack([np.sign(np.sin(r[:, 1])), np.zeros(len(q)), np.zeros(len(q))], axis=1)
    j2, j23 = r[:, 1], r[:, 1] + r[:, 2]
    reach = m.a1 + m.a2 * np.cos(j2) - m.a3 * np.cos(j23) + m.d4 * np.sin(j23)
    beta = math.atan2(m.a3, m.d4)
    return np.stack([np.sign(reach), np.sign(-np.cos(r[:, 2] - beta)), np.sign(np.sin(r[:, 4]))], axis=1)


def _configurations(m) -> list[tuple[int, int, int]]:
    if m.family == "scara":
        return [(1, 0, 0), (-1, 0, 0)]
    return [(s, e, w) for s in (1, -1) for e in (1, -1) for w in (1, -1)]


def _random_joints(m, flags: tuple[int, int, int], n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` joint vectors within the limits, all in configuration ``flags``, kept away from the singularities
    (where the configuration is not defined) by a small margin."""
    lo, hi = np.array(m.limits.min_deg), np.array(m.limits.max_deg)
    out: list[np.ndarray] = []
    have = 0
    while have < n:
        q = rng.uniform(lo, hi, size=(20 * n, m.dof))
        f = _flags(m, q)
        keep = (f == np.array(flags)).all(axis=1)
        r = np.radians(q)
        if m.family == "scara":
            keep &= np.abs(np.sin(r[:, 1])) > 1e-3
        else:
            keep &= np.abs(np.sin(r[:, 4])) > 1e-3  # away from the wrist singularity, where only J4 + J6 counts
        out.append(q[keep])
        have += int(keep.sum())
    return np.concatenate(out)[:n]


def _same_angles(a: np.ndarray, b: np.ndarray, prismatic: tuple[bool, ...]) -> np.ndarray:
    d = a - b
    rev = ~np.array(prismatic)
    d[:, rev] = (d[:, rev] + 180.0) % 360.0 - 180.0
    return np.abs(d).max(axis=1)


@pytest.fixture(params=NAMES)
def m(request):
    return model(request.param)


def test_the_registry_hands_out_each_model_by_name_and_refuses_others():
    assert set(MODELS) == {"viper-s850", "viper-s650", "cobra-s600", "cobra-s800"}
    assert model().name == DEFAULT_MODEL == "viper-s850"
    for name in NAMES:
        assert model(name).name == name
    with pytest.raises(ValueError, match=r"unknown robot model 'cobra-s1000' \(known: viper-s850"):
        model("cobra-s1000")


def test_the_viper_s850_keeps_its_numbers():
    """The paper's arm is unchanged by becoming one model among others (the real controller's home pose, docs/protocol.md; ViSP's lengths)."""
    v = model("viper-s850")
    assert (v.a1, v.d1, v.a2, v.a3, v.d4, v.d6) == (75.0, 335.0, 365.0, 90.0, 405.0, 80.0)
    assert v.forward(v.home_deg) == Pose(480.0, 0.0, 710.0, 0.0, 180.0, 0.0)
    assert v.max_speed_deg_s == (250.0, 250.0, 250.0, 375.0, 375.0, 600.0)


def test_round_trip_of_10000_random_poses_per_configuration_within_a_nanometre(m):
    """FK -> every closed-form IK solution (vectorised) -> FK: the solution in the pose's configuration is the
    joint vector we started from (mod 360) and puts the flange back within 1e-6 mm."""
    rng = np.random.default_rng(RNG_SEED)
    branches = _configurations(m)
    for b, flags in enumerate(branches):
        q = _random_joints(m, flags, N_POSES, rng)
        flanges = m.flange_matrices(q)
        sols, reached = all_solutions(m, flanges)
        assert reached[:, b].all()
        got = sols[:, b]
        again = m.flange_matrices(got)
        pos_err = np.linalg.norm(again[:, :3, 3] - flanges[:, :3, 3], axis=1)
        rot_err = np.abs(again[:, :3, :3] - flanges[:, :3, :3]).max(axis=(1, 2))
        assert pos_err.max() <= 1e-6, (m.name, flags, pos_err.max())
        assert rot_err.max() <= 1e-9, (m.name, flags, rot_err.max())
        assert (_same_angles(got, q, m.prismatic) <= 1e-6).all(), (m.name, flags)
        assert (_flags(m, got) == np.array(flags)).all()


def test_inverse_reaches_random_poses_in_the_configuration_asked_for(m):
    """The scalar inverse the controller uses: from home, asked for each configuration (V+ LEFTY/RIGHTY, ...),
    it reaches the pose and ends in that configuration."""
    rng = np.random.default_rng(RNG_SEED + 1)
    for flags in _configurations(m):
        for q in _random_joints(m, flags, 200, rng):
            pose = m.forward(q)
            got = m.inverse(pose, m.home_deg, jump=None, config=ConfigRequest(*flags))
            c = m.configuration(got)
            assert (c.shoulder, c.elbow, c.wrist) == flags
            err = np.abs(m.flange_matrix(got) - m.flange_matrix(q)).max()
            assert err <= 1e-6, (m.name, flags, q, got)
            m.limits.check(got)


def test_inverse_keeps_the_seed_configuration_and_returns_the_seed_for_its_own_pose(m):
    rng = np.random.default_rng(RNG_SEED + 2)
    for flags in _configurations(m):
        for q in _random_joints(m, flags, 100, rng):
            got = m.inverse(m.forward(q), q)
            np.testing.assert_allclose(got, q, atol=1e-6)


def test_every_joint_past_its_limit_is_refused_with_joint_limit(m):
    for i in range(m.dof):
        for end, past in ((m.limits.max_deg, 1.0), (m.limits.min_deg, -1.0)):
            q = list(m.home_deg)
            q[i] = end[i] + past
            with pytest.raises(RobotError) as e:
                m.check_joint_path(m.home_deg, q)
            assert e.value.code == ErrorCode.JOINT_LIMIT
            assert f"J{i + 1} " in str(e.value)


def test_a_pose_out_of_reach_is_refused_with_out_of_reach(m):
    far = m.forward(m.home_deg)
    far = Pose(far.x + 2 * m.reach_mm, far.y, far.z, far.yaw, far.pitch, far.roll)
    with pytest.raises(RobotError) as e:
        m.inverse(far, m.home_deg)
    assert e.value.code == ErrorCode.OUT_OF_REACH


def test_a_pose_reachable_only_past_a_limit_is_refused_with_joint_limit(m):
    """A pose whose only solution needs a joint beyond its range: J1 (and the SCARA's quill) past the limit."""
    q = list(m.home_deg)
    q[0] = m.limits.max_deg[0] + 3.0
    pose = decompose(m.flange_matrix(q))
    with pytest.raises(RobotError) as e:
        m.inverse(pose, m.home_deg, jump=None)
    assert e.value.code in (ErrorCode.JOINT_LIMIT, ErrorCode.OUT_OF_REACH)
    if m.family == "scara":
        q = list(m.home_deg)
        q[2] = m.limits.max_deg[2] + 5.0  # the quill 5 mm further down than it goes
        with pytest.raises(RobotError) as e:
            m.inverse(m.forward(q), m.home_deg, jump=None)
        assert e.value.code == ErrorCode.JOINT_LIMIT
        assert "J3" in str(e.value)


@pytest.mark.parametrize("name", [n for n in NAMES if n.startswith("cobra")])
@pytest.mark.parametrize("pitch, roll_axis", [(170.0, None), (180.0, "x")])
def test_a_scara_refuses_a_tool_that_does_not_point_down(name, pitch, roll_axis):
    """A four-axis SCARA's tool points down (V+ User's Guide, Location Variables: pitch must be 180); another
    pitch is refused, not projected onto the nearest reachable orientation."""
    m = model(name)
    here = m.forward(m.home_deg)
    bad = Pose(here.x, here.y, here.z, 0.0, pitch, here.roll)
    if roll_axis:
        bad = decompose(bad.to_matrix() @ np.array([[1, 0, 0, 0], [0, math.cos(0.1), -math.sin(0.1), 0],
                                                    [0, math.sin(0.1), math.cos(0.1), 0], [0, 0, 0, 1]]))
    with pytest.raises(RobotError, match="orientation not possible") as e:
        m.inverse(bad, m.home_deg)
    assert e.value.code == ErrorCode.OUT_OF_REACH
    # the same place with the tool down (any roll) is reachable
    ok = m.inverse(Pose(here.x, here.y, here.z, 0.0, 180.0, here.roll + 30.0), m.home_deg)
    assert m.forward(ok).roll == pytest.approx(here.roll + 30.0)


@pytest.mark.parametrize("name", [n for n in NAMES if n.startswith("cobra")])
def test_scara_location_reports_yaw_0_pitch_180_and_the_quill_in_roll_and_z(name):
    """V+: for a four-axis SCARA yaw is forced to 0 and the quill's rotation shows in roll; J3 is mm down."""
    m = model(name)
    a = m.forward((10.0, 40.0, 0.0, 0.0))
    b = m.forward((10.0, 40.0, 50.0, 25.0))
    assert (a.yaw, a.pitch, b.yaw, b.pitch) == (0.0, 180.0, 0.0, 180.0)
    assert b.z == pytest.approx(a.z - 50.0)
    assert (b.roll - a.roll) % 360.0 == pytest.approx(25.0)
    assert (b.x, b.y) == pytest.approx((a.x, a.y))
    assert m.forward((0.0, 0.0, 0.0, 0.0)).x == pytest.approx(m.a1 + m.a2)


def test_the_tool_transform_is_honoured(m):
    tool = Pose(10.0, -5.0, 120.0, 0.0, 0.0, 30.0)
    rng = np.random.default_rng(RNG_SEED + 3)
    for q in _random_joints(m, _configurations(m)[0], 50, rng):
        pose = m.forward(q, tool)
        got = m.inverse(pose, q, tool)
        np.testing.assert_allclose(got, q, atol=1e-6)
        assert np.abs((m.flange_matrix(q) @ tool.to_matrix()) - pose.to_matrix()).max() < 1e-9
    assert tool != NULL


yourdfpy = pytest.importorskip("yourdfpy")


def test_the_urdf_computes_our_flange_within_a_micrometre(m):
    robot = yourdfpy.URDF.load(io.BytesIO(urdf(m).encode()), load_meshes=False, build_collision_scene_graph=False)
    assert robot.robot.name == m.name.replace("-", "_")
    assert [j.type for j in robot.robot.joints] == ["prismatic" if p else "revolute" for p in m.prismatic]
    rng = np.random.default_rng(RNG_SEED + 4)
    lo, hi = np.array(m.limits.min_deg), np.array(m.limits.max_deg)
    for q in rng.uniform(lo, hi, size=(300, m.dof)):
        cfg = np.where(m.prismatic, q / 1000.0, np.radians(q))
        robot.update_cfg(cfg)
        theirs = robot.get_transform(FLANGE_LINK, "base_link")
        ours = m.flange_matrix(q)
        np.testing.assert_allclose(theirs[:3, 3], ours[:3, 3] / 1000.0, rtol=0, atol=1e-6)
        np.testing.assert_allclose(theirs[:3, :3], ours[:3, :3], rtol=0, atol=1e-7)
        composed = np.eye(4)
        for _parent, _child, t, r in link_transforms(m, q):
            step = np.eye(4)
            step[:3, :3], step[:3, 3] = r, t
            composed = composed @ step
        np.testing.assert_allclose(composed[:3, 3], ours[:3, 3] / 1000.0, rtol=0, atol=1e-9)
        np.testing.assert_allclose(composed[:3, :3], ours[:3, :3], rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", [n for n in NAMES if n.startswith("cobra")])
def test_a_scara_refuses_unwinding_j4_for_a_small_turn(name):
    """J4 at 355 deg and a target 10 deg further round: the nearer equivalent is past the limit, the other one is
    350 deg back, far more than a 10 deg turn of the tool justifies: refused (JOINT_JUMP), as on the Viper."""
    m = model(name)
    q = list(m.home_deg)
    q[3] = m.limits.max_deg[3] - 5.0
    target = list(q)
    target[3] += 10.0  # past the limit: the pose of J4 = -355 + ... is reachable only by unwinding
    pose = m.forward(target)
    with pytest.raises(RobotError) as e:
        m.inverse(pose, q)
    assert e.value.code == ErrorCode.JOINT_JUMP and "J4 would turn" in str(e.value)
    assert m.inverse(pose, q, jump=None)[3] == pytest.approx(target[3] - 360.0)


def test_reach_reason_tells_too_far_from_too_close_and_says_nothing_inside(m):
    """(A Viper's annulus is nearly a disc: the wrist centre is within reach of one shoulder or the other almost
    down to its J1 axis, so only a SCARA is asked for "too close".)"""
    here = m.flange_matrix(m.home_deg)
    assert m.reach_reason(here) is None
    far = here.copy()
    far[:3, 3] *= 5.0
    assert m.reach_reason(far) == "too_far"
    if m.family == "scara":
        near = here.copy()
        near[0, 3] = near[1, 3] = 0.0
        assert m.reach_reason(near) == "too_close"


@pytest.mark.parametrize("name", [n for n in NAMES if n.startswith("cobra")])
def test_a_scara_takes_the_wires_rounding_of_pitch_180_but_not_a_hundredth_of_a_degree(name):
    m = model(name)
    here = m.forward(m.home_deg)
    rounded = Pose(here.x, here.y, here.z, 0.0, 179.9995, here.roll)  # "179.9995" is what 3 decimals can leave
    assert m.inverse(rounded, m.home_deg) == pytest.approx(m.home_deg, abs=1e-3)
    with pytest.raises(RobotError, match="orientation not possible"):
        m.inverse(Pose(here.x, here.y, here.z, 0.0, 179.99, here.roll), m.home_deg)
