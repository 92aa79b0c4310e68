"""V+ location functions of the emulator (aioadept.vplus.locations) against the V+ manual and as properties."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.geometry import Pose
from aioadept.robots import viper_s850 as kin
from aioadept.vplus.locations import (
    NULL,
    PrecisionPoint,
    Transform,
    compose,
    decompose,
    distance,
    from_values,
    inverse,
    ppoint,
    rx,
    ry,
    rz,
    shift,
    trans,
)

coord = st.floats(-2000, 2000, allow_nan=False)
angle = st.floats(-179.0, 179.0, allow_nan=False)
# Away from the Z-Y-Z singularities (pitch 0 and 180), where yaw and roll are not separately defined.
pitch = st.floats(1.0, 179.0, allow_nan=False)
transforms = st.builds(trans, coord, coord, coord, angle, st.floats(0.0, 180.0), angle)


def close6(a, b, tol=1e-7):
    return all(math.isclose(x, y, abs_tol=tol) for x, y in zip(a, b, strict=True))


def test_shift_manual_example():
    # V+ Language Reference Guide, SHIFT: x = (200, 150, 100, 10, 20, 30); SHIFT(x BY 5, -5, 10)
    x = trans(200, 150, 100, 10, 20, 30)
    assert close6(decompose(shift(x, 5, -5, 10)), (205, 145, 110, 10, 20, 30))
    # an omitted shift is 0
    assert close6(decompose(shift(x, dz=1)), (200, 150, 101, 10, 20, 30))


def test_trans_defaults_and_null():
    assert trans() == NULL
    assert close6(decompose(trans(1, 2)), (1, 2, 0, 0, 0, 0))
    assert np.allclose(NULL.matrix, np.eye(4))


def test_decompose_of_home_pose_matches_the_real_ack():
    # The arm at home acks 480,0,710,0,180,0 (docs/protocol.md; tool down: pitch 180, yaw 0 by convention)
    home = Transform.from_pose(kin.forward(kin.HOME_JOINTS_DEG))
    x, y, z, yaw, p, r = decompose(home)
    assert close6((x, y, z, yaw, p), (480, 0, 710, 0, 180), tol=1e-6)
    assert math.isclose(abs(r), 0.0, abs_tol=1e-6) or math.isclose(abs(r), 180.0, abs_tol=1e-6)


def test_singular_pitch_reports_yaw_zero_but_keeps_the_rotation():
    t = trans(0, 0, 0, 30, 180, 0)
    assert t.yaw == 0.0 and math.isclose(t.pitch, 180.0)
    assert t.close(Transform.from_matrix(t.matrix))
    # the same rotation: it moves a point the same way as the matrix built from the given angles
    assert np.allclose(trans(*decompose(t)).matrix, t.matrix)


def test_compose_is_matrix_product_and_matches_geometry():
    a, b = trans(100, 0, 50, 0, 90, 0), trans(10, 0, 0, 0, 0, 0)
    # b's x axis is a's x axis turned by pitch 90: world -z
    assert close6(decompose(compose(a, b))[:3], (100, 0, 40))
    assert (a @ b) == compose(a, b)
    pa, pb = Pose(*decompose(a)), Pose(*decompose(b))
    assert (a @ b).close(Transform.from_pose(pa @ pb))


def test_rx_ry_rz():
    assert np.allclose(rz(90).matrix[:3, :3] @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(ry(90).matrix[:3, :3] @ [0, 0, 1], [1, 0, 0])
    assert np.allclose(rx(90).matrix[:3, :3] @ [0, 1, 0], [0, 0, 1])
    assert rz(30).close(trans(0, 0, 0, 0, 0, 30))


def test_distance_and_from_values():
    assert distance(trans(0, 0, 0), trans(3, 4, 0, 10, 20, 30)) == 5.0
    assert from_values((1, 2, 3, 4, 5, 6)).close(trans(1, 2, 3, 4, 5, 6))
    with pytest.raises(ValueError):
        from_values((1, 2, 3))


def test_precision_point():
    p = ppoint(0, -90, 180, 0, 90, 0)
    assert isinstance(p, PrecisionPoint)
    assert decompose(p) == (0.0, -90.0, 180.0, 0.0, 90.0, 0.0)
    assert repr(p).startswith("#PPOINT(")
    with pytest.raises(ValueError):
        PrecisionPoint(())


def test_bad_matrix_is_a_clear_error():
    with pytest.raises(ValueError, match="4x4"):
        Transform.from_matrix(np.eye(3))
    with pytest.raises(ValueError, match="12"):
        Transform((1.0, 2.0))


@given(transforms)
@settings(max_examples=200, deadline=None)
def test_inverse_then_compose_is_null(t):
    assert compose(inverse(t), t).close(NULL, tol_mm=1e-6, tol_deg=1e-6)
    assert compose(t, inverse(t)).close(NULL, tol_mm=1e-6, tol_deg=1e-6)


@given(coord, coord, coord, angle, pitch, angle)
@settings(max_examples=300, deadline=None)
def test_decompose_trans_round_trip(x, y, z, yaw, p, r):
    assert close6(decompose(trans(x, y, z, yaw, p, r)), (x, y, z, yaw, p, r), tol=1e-6)


@given(transforms, transforms, transforms)
@settings(max_examples=100, deadline=None)
def test_compose_is_associative(a, b, c):
    assert compose(compose(a, b), c).close(compose(a, compose(b, c)), tol_mm=1e-6, tol_deg=1e-6)


@given(transforms, coord, coord, coord)
@settings(max_examples=100, deadline=None)
def test_shift_moves_position_only(t, dx, dy, dz):
    s = shift(t, dx, dy, dz)
    assert np.allclose(s.matrix[:3, :3], t.matrix[:3, :3])
    assert close6((s.x, s.y, s.z), (t.x + dx, t.y + dy, t.z + dz), tol=1e-9)
