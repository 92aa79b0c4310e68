"""The Adept Cobra family (s600, s800): four-axis SCARA kinematics in the V+ joint convention, per-model constants.

Pure numpy, no I/O. Joints: J1, J2 turn about vertical axes (degrees), J3 is the quill, a prismatic axis in mm
(positive down), J4 turns the flange about the quill (degrees). The chain is the Robotics Toolbox's standard DH
model of the Cobra 600 (``mdl_cobra600``), lengths in mm::

    flange position = (a1 cos j1 + a2 cos j12,  a1 sin j1 + a2 sin j12,  d1 - j3)
    flange rotation = Rz(j1) · Rz(j2) · Rx(180) · Rz(j4) = Rz(j1 + j2 - j4) · Rx(180)

so the tool always points straight down. As the V+ User's Guide has it for a four-axis SCARA (Location
Variables, "Special Situations"): pitch is 180 deg, yaw is reported as 0 and the quill's rotation shows in the
roll; here roll = 180 + j4 - j1 - j2 (:func:`aioadept.geometry.decompose` does that by itself).

Inverse: a pose whose tool axis is not vertical (another pitch, or a roll about a horizontal axis) cannot be
reached by a four-axis SCARA: it is refused with ``OUT_OF_REACH`` ("orientation not possible ..."; V+'s own code
for it is UNCONFIRMED, docs/sim.md), never projected. Two arm solutions remain: RIGHTY (J2 > 0: seen from above,
the first two links bend like a human right arm, elbow out to the right of the line to the hand) and LEFTY
(J2 < 0); as on the Viper the seed's choice is kept unless a :class:`~aioadept.robots.base.ConfigRequest` asks for
the other, and within :data:`ELBOW_FREE_DEG` of the stretched arm (J2 = 0) either is accepted. ABOVE/BELOW and
FLIP/NOFLIP mean nothing on a SCARA and are ignored.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from aioadept.errors import RobotError
from aioadept.geometry import NULL, Pose, inverse_transform
from aioadept.protocol import ErrorCode
from aioadept.robots.base import (
    ArmMethods,
    DEFAULT_JUMP_LIMIT,
    ConfigRequest,
    Configuration,
    JointLimits,
    JumpLimit,
    UrdfJoint,
    jump_excess,
    nearest_solution,
    sign,
)

ELBOW_FREE_DEG = 5.0
"""Within this many degrees of J2 = 0 (the stretched arm, where LEFTY meets RIGHTY) the seed's choice is not kept."""

TILT_TOLERANCE_RAD = 1e-5
"""How far the tool axis of a target may lean off vertical (radians) and still count as pointing down: the wire's
rounding of angles to 3 decimals (0.0005 deg = 8.7e-6 rad), not a tilt anybody asked for; the solution ignores
it (0.001 mm at the tip of a 100 mm tool)."""


@dataclass(frozen=True)
class Scara(ArmMethods):
    """One Cobra model: its name, link lengths (mm), joint limits (deg, J3 mm), joint speeds (deg/s, J3 mm/s) and
    home. ``d1`` is the flange's height above the base frame with J3 at 0 (the quill up)."""

    name: str
    a1: float
    a2: float
    d1: float
    limits: JointLimits
    max_speed_deg_s: tuple[float, ...]
    home_deg: tuple[float, ...]
    family: str = field(default="scara", init=False)
    dof: int = field(default=4, init=False)
    prismatic: tuple[bool, ...] = field(default=(False, False, True, False), init=False)

    def __post_init__(self) -> None:
        if len(self.limits.min_deg) != 4 or len(self.max_speed_deg_s) != 4 or len(self.home_deg) != 4:
            raise ValueError(f"{self.name}: a SCARA has 4 joints")
        self.limits.check(self.home_deg)

    @property
    def reach_mm(self) -> float:
        return self.a1 + self.a2

    # -- forward ---------------------------------------------------------------------------------------------
    def configuration(self, joints_deg: Sequence[float]) -> Configuration:
        """RIGHTY (+1, J2 > 0) or LEFTY (-1); 0 on the stretched arm."""
        return Configuration(sign(math.sin(math.radians(joints_deg[1])), 1e-6), 0, 0)

    def flange_matrix(self, joints_deg: Sequence[float]) -> np.ndarray:
        """4x4 transform of the flange in the robot base frame (mm) for joints in degrees (J3 in mm)."""
        if len(joints_deg) != 4:
            raise ValueError(f"joints_deg: expected 4 values, got {len(joints_deg)}")
        return self.flange_matrices(np.asarray([joints_deg], dtype=float))[0]

    def flange_matrices(self, joints_deg: np.ndarray) -> np.ndarray:
        """4x4 flange transforms (M, 4, 4) of joint vectors (M, 4)."""
        q = np.asarray(joints_deg, dtype=float)
        j1, j12 = np.radians(q[:, 0]), np.radians(q[:, 0] + q[:, 1])
        phi = np.radians(q[:, 0] + q[:, 1] - q[:, 3])
        c, s = np.cos(phi), np.sin(phi)
        m = np.zeros((len(q), 4, 4))
        # Rz(phi) Rx(180): x = (c, s, 0), y = (s, -c, 0), z = (0, 0, -1)
        m[:, 0, 0], m[:, 1, 0] = c, s
        m[:, 0, 1], m[:, 1, 1] = s, -c
        m[:, 2, 2] = -1.0
        m[:, 0, 3] = self.a1 * np.cos(j1) + self.a2 * np.cos(j12)
        m[:, 1, 3] = self.a1 * np.sin(j1) + self.a2 * np.sin(j12)
        m[:, 2, 3] = self.d1 - q[:, 2]
        m[:, 3, 3] = 1.0
        return m

    # -- inverse ---------------------------------------------------------------------------------------------
    def solutions(self, m: np.ndarray) -> list[tuple[tuple[float, ...], Configuration]]:
        """The two arm solutions (deg, J3 mm; angles in (-180, 180]) of a flange transform, RIGHTY first.

        Raises ``RobotError(OUT_OF_REACH)`` when the tool axis is not vertical (pointing down) or the position is
        out of the arm's reach."""
        tilt = math.hypot(m[0, 2], m[1, 2])
        if m[2, 2] > 0 or tilt > TILT_TOLERANCE_RAD:
            pitch = math.degrees(math.atan2(tilt, -m[2, 2]))
            raise RobotError(ErrorCode.OUT_OF_REACH,
                             f"orientation not possible: a SCARA's tool points down (tilt {pitch:.3f} deg)")
        x, y, z = float(m[0, 3]), float(m[1, 3]), float(m[2, 3])
        r2 = x * x + y * y
        c2 = (r2 - self.a1 ** 2 - self.a2 ** 2) / (2.0 * self.a1 * self.a2)
        if c2 > 1.0 + 1e-12 or c2 < -1.0 - 1e-12:
            raise RobotError(ErrorCode.OUT_OF_REACH,
                             f"location out of range ({math.sqrt(r2):.1f} mm from the J1 axis)")
        c2 = max(-1.0, min(1.0, c2))
        phi = math.degrees(math.atan2(float(m[1, 0]), float(m[0, 0])))
        out = []
        for righty in (1, -1):
            j2 = righty * math.acos(c2)
            j1 = math.atan2(y, x) - math.atan2(self.a2 * math.sin(j2), self.a1 + self.a2 * math.cos(j2))
            j1d, j2d = math.degrees(j1), math.degrees(j2)
            j4 = j1d + j2d - phi
            out.append(((j1d, j2d, self.d1 - z, j4), Configuration(sign(math.sin(j2), 1e-9), 0, 0)))
        return out

    def all_solutions(self, flanges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Both arm solutions of N flange transforms at once: joints (N, 2, 4), RIGHTY then LEFTY, as
        :meth:`solutions` computes each, and ``reached`` (N, 2): within reach with the tool pointing down."""
        m = np.asarray(flanges, dtype=float)
        x, y = m[:, 0, 3], m[:, 1, 3]
        c2 = (x * x + y * y - self.a1 ** 2 - self.a2 ** 2) / (2.0 * self.a1 * self.a2)
        down = (m[:, 2, 2] < 0) & (np.hypot(m[:, 0, 2], m[:, 1, 2]) <= TILT_TOLERANCE_RAD)
        ok = down & (np.abs(c2) <= 1.0 + 1e-12)
        phi = np.degrees(np.arctan2(m[:, 1, 0], m[:, 0, 0]))
        out = np.empty((len(m), 2, 4))
        for b, righty in enumerate((1.0, -1.0)):
            j2 = righty * np.arccos(np.clip(c2, -1.0, 1.0))
            j1 = np.arctan2(y, x) - np.arctan2(self.a2 * np.sin(j2), self.a1 + self.a2 * np.cos(j2))
            out[:, b, 0], out[:, b, 1] = np.degrees(j1), np.degrees(j2)
            out[:, b, 2] = self.d1 - m[:, 2, 3]
            out[:, b, 3] = out[:, b, 0] + out[:, b, 1] - phi
        return out, np.repeat(ok[:, None], 2, axis=1)

    def reach_reason(self, flange: np.ndarray) -> str | None:
        """``"too_far"``/``"too_close"`` when the flange lies outside the annulus J1 and J2 sweep, else None (the
        orientation, J3's stroke or the configuration is the reason)."""
        r = math.hypot(flange[0, 3], flange[1, 3])
        if r > self.a1 + self.a2:
            return "too_far"
        return "too_close" if r < abs(self.a1 - self.a2) else None

    def inverse(self, pose: Pose, current_joints_deg: Sequence[float], tool: Pose = NULL, *,
                limits: JointLimits | None = None,
                jump: JumpLimit | None = DEFAULT_JUMP_LIMIT,
                config: ConfigRequest | None = None) -> tuple[float, ...]:
        """Inverse kinematics: joints that put the tool at ``pose``, continuing from ``current_joints_deg``.

        The seed's LEFTY/RIGHTY is kept (either near the stretched arm), or the one ``config`` asks for; each
        revolute joint takes its equivalent (+-360 deg) nearest the seed within ``limits`` (default: the model's);
        the jump check is the Viper's (:class:`~aioadept.robots.base.JumpLimit`). ``config.single`` keeps J4
        within -180..180 deg.

        Raises ``RobotError`` with ``OUT_OF_REACH`` (out of reach, orientation not possible, or no solution in the
        configuration), ``JOINT_LIMIT``, ``JOINT_JUMP``, ``ILLEGAL_VALUE`` for a pose that is not finite.
        """
        if len(current_joints_deg) != 4:
            raise ValueError(f"current_joints_deg: expected 4 values, got {len(current_joints_deg)}")
        limits = self.limits if limits is None else limits
        cur = [float(v) for v in current_joints_deg]
        m = pose.to_matrix()
        if tool != NULL:
            m = m @ inverse_transform(tool.to_matrix())
        if not np.isfinite(m).all():
            raise RobotError(ErrorCode.ILLEGAL_VALUE, "location is not finite")
        s2 = math.sin(math.radians(cur[1]))
        want = 0 if abs(s2) < math.sin(math.radians(ELBOW_FREE_DEG)) else (1 if s2 > 0 else -1)
        changing = False
        lo, hi = list(limits.min_deg), list(limits.max_deg)
        if config is not None:
            changing = config.changes(cur, self) or (config.single and abs(cur[3]) > 180.0 + 1e-9)
            want = config.shoulder or want
            if config.single:
                lo[3], hi[3] = max(lo[3], -180.0), min(hi[3], 180.0)
        candidates = [(sol, c) for sol, c in self.solutions(m) if not want or not c.shoulder or c.shoulder == want]
        best = nearest_solution((sol for sol, _ in candidates), cur, lo, hi, self.prismatic)
        if best is None:
            if not candidates:
                raise RobotError(ErrorCode.OUT_OF_REACH, "location out of range in the current configuration")
            sol = candidates[0][0]
            limits.check([v if self.prismatic[i] else v + 360.0 * round((cur[i] - v) / 360.0)
                          for i, v in enumerate(sol)])
            raise RobotError(ErrorCode.JOINT_LIMIT, "no solution within the joint limits")
        excess = None if jump is None or changing else jump_excess(self, best, cur, m, tool, jump)
        if excess is not None:
            worst, moved, distance, rotation, allowed = excess
            raise RobotError(ErrorCode.JOINT_JUMP, f"J{worst + 1} would turn {moved:.1f} deg for {distance:.2f} mm "
                                                   f"{rotation:.2f} deg (max {allowed:.1f})")
        return tuple(best)

    # -- description ---------------------------------------------------------------------------------------------
    @property
    def urdf_joints(self) -> tuple[UrdfJoint, ...]:
        """The chain, base to flange: J1 about z at height d1, J2 about z at a1, the quill sliding down at a2, J4
        turning the flange (which points down: the fixed roll of 180 deg) about its own z."""
        z = (0.0, 0.0, 1.0)
        return (
            UrdfJoint("joint_1", "base_link", "link_1", (0.0, 0.0, self.d1), z),
            UrdfJoint("joint_2", "link_1", "link_2", (self.a1, 0.0, 0.0), z),
            UrdfJoint("joint_3", "link_2", "link_3", (self.a2, 0.0, 0.0), (0.0, 0.0, -1.0), prismatic=True),
            UrdfJoint("joint_4", "link_3", "flange", (0.0, 0.0, 0.0), z, origin_rpy=(math.pi, 0.0, 0.0)),
        )

    def describe(self) -> str:
        return f"a1={self.a1:g} a2={self.a2:g} d1={self.d1:g} mm"


_DEFAULT_SPEEDS = (360.0, 360.0, 1000.0, 720.0)
"""CONFIGURABLE DEFAULT, not a vendor figure: no public source gives the Cobras' joint speeds (docs/sim.md)."""

COBRA_S600 = Scara("cobra-s600", a1=325.0, a2=275.0, d1=387.0,
                   limits=JointLimits((-105.0, -150.0, 0.0, -360.0), (105.0, 150.0, 210.0, 360.0)),
                   max_speed_deg_s=_DEFAULT_SPEEDS, home_deg=(0.0, 90.0, 100.0, 0.0))
"""Robotics Toolbox ``mdl_cobra600`` (a1, a2, d1, J3 stroke); J1, J2, J4 ranges from robotkinematicscatalogue's
``Adept_Cobra_s600`` (docs/sim.md says why)."""

COBRA_S800 = Scara("cobra-s800", a1=425.0, a2=375.0, d1=387.0,
                   limits=JointLimits((-105.0, -157.0, 0.0, -360.0), (105.0, 157.0, 210.0, 360.0)),
                   max_speed_deg_s=_DEFAULT_SPEEDS, home_deg=(0.0, 90.0, 100.0, 0.0))
"""robotkinematicscatalogue's ``Adept_Cobra_s800_inverted`` (a1, a2, joint ranges); d1 is a CONFIGURABLE DEFAULT
(the s600's: the only public s800 figure is for the inverted mount)."""

__all__ = ["COBRA_S600", "COBRA_S800", "ELBOW_FREE_DEG", "TILT_TOLERANCE_RAD", "Scara"]
