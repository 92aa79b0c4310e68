"""V+ location values for the emulator: transformations, precision points and their functions.

Pure math, no robot and no time. The interpreter evaluates ``TRANS``, ``DECOMPOSE``, ``INVERSE``, ``a:b``,
``SHIFT``, ``RX``/``RY``/``RZ``, ``DISTANCE`` and ``#PPOINT`` with these; :mod:`aioadept.vplus.robot` turns them
into motions of the simulated controller. The rotation convention is the one of :mod:`aioadept.geometry` (Adept
``TRANS`` is Z-Y-Z Euler, ``R = Rz(yaw) · Ry(pitch) · Rz(roll)``), which this module builds on instead of
repeating it.

A :class:`Transform` holds its homogeneous matrix, as the controller does (V+ stores a transformation as a 3x4
matrix, see ``TRANSB`` in the V+ Language Reference Guide), and reports ``x, y, z, yaw, pitch, roll`` by
decomposing it. So ``TRANS(0, 0, 0, 30, 180, 0)`` reads back as yaw 0, roll -30 (or an equivalent triple): the
same rotation, in the form V+ ``DECOMPOSE`` gives at a singular pitch. Compare rotations with
:meth:`Transform.close`, never the six numbers.

Differences from a controller that are known: values are float64 (V+ stores transformations in single
precision, so the last digits of a decomposed value may differ from a controller's by about 1e-5 mm).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from aioadept.geometry import Pose, inverse_transform, pose_error, rot_y, rot_z, rotation_to_zyz
from aioadept.geometry import trans as _trans_matrix

__all__ = [
    "NULL", "PrecisionPoint", "Transform", "compose", "decompose", "distance", "inverse", "ppoint", "rx", "ry",
    "rz", "shift", "trans", "from_values",
]


@dataclass(frozen=True, slots=True)
class Transform:
    """A V+ transformation (location): the 3x4 matrix ``[R | p]`` row by row, ``p`` in mm.

    Build one with :func:`trans` (six numbers) or :meth:`from_matrix`; read it with :attr:`x` ... :attr:`roll`,
    :meth:`decompose` or :attr:`matrix`. Equality is exact equality of the twelve numbers.
    """

    rows: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.rows) != 12:
            raise ValueError(f"Transform: expected 12 matrix entries, got {len(self.rows)}")

    # -- construction -----------------------------------------------------------------------------------
    @classmethod
    def from_matrix(cls, m: np.ndarray | Sequence[Sequence[float]]) -> Transform:
        """From a 4x4 (or 3x4) homogeneous matrix in mm."""
        a = np.asarray(m, dtype=float)
        if a.shape not in ((4, 4), (3, 4)):
            raise ValueError(f"Transform.from_matrix: expected a 4x4 or 3x4 matrix, got shape {a.shape}")
        return cls(tuple(float(v) for v in a[:3, :].reshape(12)))

    @classmethod
    def from_pose(cls, pose: Pose) -> Transform:
        # HERE of a robot at rest asks for the same pose again and again (every ack of the server does): the
        # last one is kept (the function is pure; the numpy rotation took most of an ack's HERE)
        xs = pose.as_tuple()
        key = _pack6(*xs)                  # bit-exact: 0.0 and -0.0 give different signs downstream
        last = _LAST_POSE
        if last[0] == key and cls is Transform:
            return last[1]
        t = trans(*xs)
        if cls is Transform:
            _LAST_POSE[:] = [key, t]
        return t

    # -- reading ----------------------------------------------------------------------------------------
    @property
    def matrix(self) -> np.ndarray:
        """The 4x4 homogeneous matrix (a new array each time)."""
        m = np.eye(4)
        m[:3, :] = np.asarray(self.rows).reshape(3, 4)
        return m

    @property
    def x(self) -> float:
        return self.rows[3]

    @property
    def y(self) -> float:
        return self.rows[7]

    @property
    def z(self) -> float:
        return self.rows[11]

    @property
    def yaw(self) -> float:
        return self.decompose()[3]

    @property
    def pitch(self) -> float:
        return self.decompose()[4]

    @property
    def roll(self) -> float:
        return self.decompose()[5]

    def decompose(self) -> tuple[float, float, float, float, float, float]:
        """V+ ``DECOMPOSE``: ``(x, y, z, yaw, pitch, roll)`` in mm and degrees; yaw = 0 at pitch 0 or 180."""
        r = self.rows
        last = _LAST_DECOMPOSED
        if last[0] is r:
            return last[1]                 # the same location again (HERE at rest), a pure function of rows
        rot = np.array(((r[0], r[1], r[2]), (r[4], r[5], r[6]), (r[8], r[9], r[10])))
        yaw, pitch, roll = rotation_to_zyz(rot)
        out = (r[3], r[7], r[11], yaw, pitch, roll)
        _LAST_DECOMPOSED[:] = [r, out]
        return out

    def to_pose(self) -> Pose:
        """The same location as the :class:`aioadept.geometry.Pose` the controller model takes."""
        return Pose(*self.decompose())

    def close(self, other: Transform, *, tol_mm: float = 1e-6, tol_deg: float = 1e-6) -> bool:
        """Same location within the tolerances (rotations compared as rotations, not as Euler angles)."""
        dist, angle = pose_error(self.to_pose(), other.to_pose())
        return dist <= tol_mm and angle <= tol_deg

    # -- operators --------------------------------------------------------------------------------------
    def __matmul__(self, other: Transform) -> Transform:
        """V+ ``self:other``."""
        if not isinstance(other, Transform):
            return NotImplemented
        return compose(self, other)

    def __repr__(self) -> str:
        return "Transform(%s)" % ", ".join("%.3f" % v for v in self.decompose())


@dataclass(frozen=True, slots=True)
class PrecisionPoint:
    """A V+ precision point (``#name``): one angle per joint, in degrees."""

    joints_deg: tuple[float, ...]

    def __post_init__(self) -> None:
        if not self.joints_deg:
            raise ValueError("PrecisionPoint: needs at least one joint")
        object.__setattr__(self, "joints_deg", tuple(float(v) for v in self.joints_deg))

    def decompose(self) -> tuple[float, ...]:
        """V+ ``DECOMPOSE`` of a precision point: the joint values."""
        return self.joints_deg

    def __repr__(self) -> str:
        return "#PPOINT(%s)" % ", ".join("%.3f" % v for v in self.joints_deg)


_LAST_POSE: list = [None, None]           # (packed pose, Transform) of the last Transform.from_pose
_LAST_DECOMPOSED: list = [None, None]     # (rows object, six numbers) of the last Transform.decompose
_pack6 = struct.Struct("<6d").pack


def trans(x: float = 0.0, y: float = 0.0, z: float = 0.0, yaw: float = 0.0, pitch: float = 0.0,
          roll: float = 0.0) -> Transform:
    """V+ ``TRANS(x, y, z, yaw, pitch, roll)``: mm and degrees; omitted values are 0."""
    return Transform.from_matrix(_trans_matrix(x, y, z, yaw, pitch, roll))


NULL = trans()
"""V+ ``NULL``: the identity transformation."""


def ppoint(*joints_deg: float) -> PrecisionPoint:
    """V+ ``#PPOINT(j1, j2, ...)``."""
    return PrecisionPoint(tuple(joints_deg))


def decompose(value: Transform | PrecisionPoint) -> tuple[float, ...]:
    """V+ ``DECOMPOSE``: six numbers of a transformation, the joint angles of a precision point."""
    return value.decompose()


def compose(a: Transform, b: Transform) -> Transform:
    """V+ ``a:b``: ``b`` expressed in the frame of ``a`` (matrix product)."""
    return Transform.from_matrix(a.matrix @ b.matrix)


def inverse(t: Transform) -> Transform:
    """V+ ``INVERSE(t)``: the transformation with ``INVERSE(t):t == NULL``."""
    return Transform.from_matrix(inverse_transform(t.matrix))


def shift(t: Transform, dx: float = 0.0, dy: float = 0.0, dz: float = 0.0) -> Transform:
    """V+ ``SHIFT(t BY dx, dy, dz)``: the position components plus the shifts (world axes), rotation kept."""
    r = list(t.rows)
    r[3] += dx
    r[7] += dy
    r[11] += dz
    return Transform(tuple(r))


def _rotation(rot: np.ndarray) -> Transform:
    m = np.eye(4)
    m[:3, :3] = rot
    return Transform.from_matrix(m)


def rx(angle_deg: float) -> Transform:
    """V+ ``RX(angle)``: a rotation about the X axis, no translation."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    return _rotation(np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]))


def ry(angle_deg: float) -> Transform:
    """V+ ``RY(angle)``: a rotation about the Y axis, no translation."""
    return _rotation(rot_y(angle_deg))


def rz(angle_deg: float) -> Transform:
    """V+ ``RZ(angle)``: a rotation about the Z axis, no translation."""
    return _rotation(rot_z(angle_deg))


def distance(a: Transform, b: Transform) -> float:
    """V+ ``DISTANCE(a, b)``: distance in mm between the positions of two transformations."""
    return math.dist((a.x, a.y, a.z), (b.x, b.y, b.z))


def from_values(values: Iterable[float]) -> Transform:
    """A transformation from six numbers (the inverse of :func:`decompose`); ``ValueError`` for another count."""
    vals = tuple(float(v) for v in values)
    if len(vals) != 6:
        raise ValueError(f"expected 6 values, got {len(vals)}")
    return trans(*vals)


ROTATION_TOLERANCE = 1e-3
"""How far a stored rotation may be from orthonormal (STORE writes about 6 significant digits)."""


def by_column(nums: Sequence[float]) -> tuple[float, ...]:
    """12 numbers of a transformation by column, as STORE and ``$TRANSB`` give them (V+ Language Reference Guide,
    ``TRANSB``/``$TRANSB``: x axis, y axis, z axis, position), to the row-major 3x4 of :class:`Transform`;
    ``ValueError`` if the rotation is none (not orthonormal within :data:`ROTATION_TOLERANCE`, or a reflection)."""
    cols = [nums[0:3], nums[3:6], nums[6:9]]
    for i in range(3):
        for j in range(i, 3):
            dot = sum(cols[i][k] * cols[j][k] for k in range(3))
            if abs(dot - (1.0 if i == j else 0.0)) > ROTATION_TOLERANCE:
                raise ValueError("its 3x3 rotation (the first 9 of the 12 values, by column) is not orthonormal")
    x, y, z = cols
    det = (x[0] * (y[1] * z[2] - y[2] * z[1]) - y[0] * (x[1] * z[2] - x[2] * z[1])
           + z[0] * (x[1] * y[2] - x[2] * y[1]))
    if det < 0:
        raise ValueError("its 3x3 rotation (the first 9 of the 12 values, by column) is a reflection")
    p = nums[9:12]
    return tuple(float(v) for r in range(3) for v in (x[r], y[r], z[r], p[r]))


def columns(t: Transform) -> tuple[float, ...]:
    """The 12 numbers of ``t`` by column (the inverse of :func:`by_column`)."""
    r = t.rows
    return tuple(r[4 * row + col] for col in range(4) for row in range(3))
