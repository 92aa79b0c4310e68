"""Locations as V+ knows them: poses in mm and degrees, Adept TRANS (Z-Y-Z Euler) conversions and composition.

A :class:`Pose` is what an ack carries and what ``move_to`` takes. It is shared by the client, the protocol core and
the simulated controller. Rotation convention (Adept ``TRANS``): ``R = Rz(yaw) · Ry(pitch) · Rz(roll)``.
``a @ b`` composes like V+ ``a:b`` (``b`` expressed in ``a``'s frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Iterator

import numpy as np

# Below this |sin(pitch)| the Z-Y-Z decomposition is singular (pitch ~ 0 or 180 deg); V+ then reports yaw = 0.
_SINGULAR_EPS = 1e-9


@dataclass(frozen=True, slots=True)
class Pose:
    """A location: translation ``x, y, z`` in mm, rotation ``yaw, pitch, roll`` in degrees (Z-Y-Z Euler)."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    yaw: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0

    @classmethod
    def from_seq(cls, values: Iterable[float]) -> Pose:
        """Build from six numbers ``x, y, z, yaw, pitch, roll``; raises ``ValueError`` for another count."""
        vals = tuple(float(v) for v in values)
        if len(vals) != 6:
            raise ValueError(f"pose: expected 6 values, got {len(vals)}")
        return cls(*vals)

    def as_tuple(self) -> tuple[float, float, float, float, float, float]:
        return (self.x, self.y, self.z, self.yaw, self.pitch, self.roll)

    def __iter__(self) -> Iterator[float]:
        return iter(self.as_tuple())

    @property
    def position_mm(self) -> np.ndarray:
        return np.array([self.x, self.y, self.z])

    def to_matrix(self) -> np.ndarray:
        """The 4x4 homogeneous transform (mm) of this pose."""
        return trans(*self.as_tuple())

    @classmethod
    def from_matrix(cls, m: np.ndarray) -> Pose:
        """Decompose a 4x4 homogeneous transform as V+ DECOMPOSE does."""
        return decompose(m)

    def __matmul__(self, other: Pose) -> Pose:
        """V+ ``self:other``: ``other`` applied in the frame of ``self``."""
        if not isinstance(other, Pose):
            return NotImplemented
        return decompose(self.to_matrix() @ other.to_matrix())

    def inverse(self) -> Pose:
        """V+ ``INVERSE(self)``."""
        return decompose(inverse_transform(self.to_matrix()))

    def translation_distance_mm(self, other: Pose) -> float:
        return math.dist((self.x, self.y, self.z), (other.x, other.y, other.z))


NULL = Pose()
"""V+ ``NULL``: the identity location."""


def rot_z(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_y(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def zyz_to_rotation(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Rotation matrix of Adept (yaw, pitch, roll) in degrees: ``Rz(yaw) Ry(pitch) Rz(roll)``."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_z(roll)


def rotation_to_zyz(r: np.ndarray) -> tuple[float, float, float]:
    """(yaw, pitch, roll) in degrees of a rotation matrix; at pitch 0 or 180 the yaw is set to 0 as in V+."""
    sp = math.hypot(r[2, 0], r[2, 1])
    pitch = math.atan2(sp, r[2, 2])
    if sp < _SINGULAR_EPS:
        yaw = 0.0
        # Only yaw+roll (pitch 0) or roll-yaw (pitch 180) is defined; put it all in roll.
        if r[2, 2] > 0:
            roll = math.atan2(r[1, 0], r[0, 0])
        else:
            roll = math.atan2(r[1, 0], -r[0, 0])
    else:
        yaw = math.atan2(r[1, 2], r[0, 2])
        roll = math.atan2(r[2, 1], -r[2, 0])
    return (math.degrees(yaw), math.degrees(pitch), math.degrees(roll))


def trans(x: float = 0.0, y: float = 0.0, z: float = 0.0, yaw: float = 0.0, pitch: float = 0.0,
          roll: float = 0.0) -> np.ndarray:
    """V+ ``TRANS(x, y, z, yaw, pitch, roll)`` as a 4x4 homogeneous matrix (mm, degrees)."""
    m = np.eye(4)
    m[:3, :3] = zyz_to_rotation(yaw, pitch, roll)
    m[:3, 3] = (x, y, z)
    return m


def decompose(m: np.ndarray) -> Pose:
    """V+ ``DECOMPOSE``: a 4x4 homogeneous matrix to a :class:`Pose`."""
    yaw, pitch, roll = rotation_to_zyz(m[:3, :3])
    return Pose(float(m[0, 3]), float(m[1, 3]), float(m[2, 3]), yaw, pitch, roll)


def inverse_transform(m: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform."""
    inv = np.eye(4)
    rt = m[:3, :3].T
    inv[:3, :3] = rt
    inv[:3, 3] = -rt @ m[:3, 3]
    return inv


def rel_world(pose: Pose, delta: Pose | Iterable[float]) -> Pose:
    """AdeptServer's ``move_rel_world`` target: the six numbers added component-wise, angles included.

    ``TRANS(x+dx, y+dy, z+dz, yaw+dyaw, pitch+dpitch, roll+droll)`` of the decomposed current pose; rotations are
    not composed (that is what the original V+ program does).
    """
    d = delta if isinstance(delta, Pose) else Pose.from_seq(delta)
    return Pose(*(a + b for a, b in zip(pose.as_tuple(), d.as_tuple(), strict=True)))


def rel_tool(pose: Pose, delta: Pose | Iterable[float]) -> Pose:
    """``move_rel_tool`` target: V+ ``pose:TRANS(delta)``, the displacement expressed in the tool frame."""
    d = delta if isinstance(delta, Pose) else Pose.from_seq(delta)
    return decompose(pose.to_matrix() @ d.to_matrix())


def pose_error(a: Pose, b: Pose) -> tuple[float, float]:
    """(translation distance in mm, rotation angle in degrees) between two poses.

    Compares rotation matrices, so equivalent Euler triples (e.g. at pitch 180) count as equal.
    """
    r = zyz_to_rotation(a.yaw, a.pitch, a.roll).T @ zyz_to_rotation(b.yaw, b.pitch, b.roll)
    # atan2 of the axis-angle sine and cosine stays precise near 0, where acos(trace) loses half the digits.
    sin_angle = 0.5 * math.sqrt((r[2, 1] - r[1, 2]) ** 2 + (r[0, 2] - r[2, 0]) ** 2 + (r[1, 0] - r[0, 1]) ** 2)
    cos_angle = (float(np.trace(r)) - 1.0) / 2.0
    angle = math.degrees(math.atan2(sin_angle, cos_angle))
    return a.translation_distance_mm(b), angle


def poses_close(a: Pose, b: Pose, *, tol_mm: float = 1e-6, tol_deg: float = 1e-6) -> bool:
    """True when ``a`` and ``b`` are the same location within the tolerances (see :func:`pose_error`)."""
    dist_mm, angle_deg = pose_error(a, b)
    return dist_mm <= tol_mm and angle_deg <= tol_deg
