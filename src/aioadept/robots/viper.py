"""The Adept Viper family (s650, s850): six-axis kinematics in the V+ joint convention, one class, per-model constants.

Pure numpy, no I/O. A :class:`Viper` is a value: its link lengths, joint limits, joint speeds and home pose; its
methods are the forward and inverse kinematics the simulated controller plans every motion with.

Model (ViSP ``vpViper850`` / ``vpViper650``, docs/sim.md "Robot models"), lengths in mm::

    s850: a1 = 75, d1 = 335, a2 = 365, a3 = 90, d4 = 405, d6 = 80 (flange)
    s650: a1 = 75, d1 = 335, a2 = 270, a3 = 90, d4 = 295, d6 = 80

In the V+ convention the chain factors as

    R      = Rz(j1) · Ry(j2 + j3) · Rz(j4) · Ry(j5) · Rz(j6)
    wrist  = Rz(j1) · (a1 + a2 cos j2 - a3 cos j23 + d4 sin j23,  0,  d1 - a2 sin j2 + a3 sin j23 + d4 cos j23)
    flange = wrist + d6 · R[:, 2]

which is ViSP's closed-form ``get_fMe`` written compactly. Home ``[0, -90, 180, 0, 90, 0]`` gives, on the s850,
``(480, 0, 710, 0, 180, 0)``: upper arm vertical, forearm horizontal, tool pointing down - the pose of
the acks in docs/protocol.md. The wrist is spherical, so the inverse is closed form: position of the wrist centre gives
j1..j3 (two shoulder and two elbow solutions), the remaining rotation gives j4..j6 as Z-Y-Z angles (two wrist
solutions), and J4/J6 may add multiples of 360 deg within their limits.

:meth:`Viper.inverse` continues from the current joints: it keeps the arm configuration, takes the nearest
solution, and refuses (``JOINT_JUMP``) a target whose joint motion is out of proportion to its Cartesian size
(:class:`~aioadept.robots.base.JumpLimit`), so that a small command can never flip the wrist or swing a joint round
a singularity.

A robot-related failure raises :class:`aioadept.errors.RobotError` with ``code`` from
:class:`aioadept.protocol.ErrorCode` (``OUT_OF_REACH``, ``JOINT_LIMIT`` or ``JOINT_JUMP``), so the controller can
turn it into an ``error`` ack, before any motion, without translating.
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
    matches,
    jump_excess,
    nearest_solution,
    sign,
    wrap_pi,
)

WRIST_SINGULAR_SIN = 1e-4
"""Below this sin(J5) the wrist counts as singular: J4 keeps the seed value and J5, J6 are fitted to the target.
The fit leaves an orientation error of at most this many radians (0.006 deg: 0.008 mm at the flange, 0.03 mm at
the tip of a 300 mm tool, within the Viper's repeatability); everywhere else the solution is exact."""

WRIST_FREE_DEG = 5.0
"""Within this many degrees of J5 = 0 (the wrist singularity) the seed's FLIP/NOFLIP is not kept: both wrist
branches are candidates and the one nearest the seed wins, so J5 may pass through zero with J4 staying put instead
of J4 and J6 turning half a revolution to keep the sign of J5."""

SHOULDER_FREE_MM = 10.0
"""Within this distance of the wrist centre from the J1 axis the seed's LEFTY/RIGHTY is not kept (same reason)."""

ELBOW_FREE_DEG = 5.0
"""Within this many degrees of the stretched (or folded) elbow the seed's ABOVE/BELOW is not kept (same reason)."""


def _rz(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz_many(t: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(t), np.sin(t), np.zeros_like(t), np.ones_like(t)
    return np.stack([c, -s, z, s, c, z, z, z, o], axis=-1).reshape(-1, 3, 3)


def _ry_many(t: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(t), np.sin(t), np.zeros_like(t), np.ones_like(t)
    return np.stack([c, z, s, z, o, z, -s, z, c], axis=-1).reshape(-1, 3, 3)


_Z = (0.0, 0.0, 1.0)
_Y = (0.0, 1.0, 0.0)


@dataclass(frozen=True)
class Viper(ArmMethods):
    """One Viper model: its name, link lengths (mm), software joint limits (deg), joint speeds (deg/s) and home."""

    name: str
    a1: float
    d1: float
    a2: float
    a3: float
    d4: float
    d6: float
    limits: JointLimits
    max_speed_deg_s: tuple[float, ...]
    home_deg: tuple[float, ...] = (0.0, -90.0, 180.0, 0.0, 90.0, 0.0)
    family: str = field(default="viper", init=False)
    dof: int = field(default=6, init=False)
    prismatic: tuple[bool, ...] = field(default=(False,) * 6, init=False)
    l3: float = field(init=False)
    """The forearm as one link from elbow to wrist centre: its length, and (:attr:`beta`) its angle off d4."""
    beta: float = field(init=False)
    reach_mm: float = field(init=False)
    """Largest distance of the wrist centre from the J1 axis (about 854.9 mm on the s850, the datasheet reach)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "l3", math.hypot(self.a3, self.d4))
        object.__setattr__(self, "beta", math.atan2(self.a3, self.d4))
        object.__setattr__(self, "reach_mm", self.a1 + self.a2 + self.l3)
        if len(self.limits.min_deg) != 6 or len(self.max_speed_deg_s) != 6 or len(self.home_deg) != 6:
            raise ValueError(f"{self.name}: a Viper has 6 joints")
        self.limits.check(self.home_deg)

    # -- forward ---------------------------------------------------------------------------------------------
    def arm_plane(self, j2: float, j3: float) -> tuple[float, float]:
        """Wrist centre in the arm plane: (radial distance from the J1 axis, height), radians in, mm out."""
        j23 = j2 + j3
        r = self.a1 + self.a2 * math.cos(j2) - self.a3 * math.cos(j23) + self.d4 * math.sin(j23)
        z = self.d1 - self.a2 * math.sin(j2) + self.a3 * math.sin(j23) + self.d4 * math.cos(j23)
        return r, z

    def configuration(self, joints_deg: Sequence[float]) -> Configuration:
        """The arm configuration of a joint vector."""
        j = [math.radians(v) for v in joints_deg]
        r, _ = self.arm_plane(j[1], j[2])
        return Configuration(
            shoulder=sign(r, 1e-3),
            elbow=sign(-math.cos(j[2] - self.beta), 1e-6),
            wrist=sign(math.sin(j[4]), 1e-6),
        )

    def flange_matrix(self, joints_deg: Sequence[float]) -> np.ndarray:
        """4x4 transform of the flange in the robot base frame (mm) for joints in degrees."""
        if len(joints_deg) != 6:
            raise ValueError(f"joints_deg: expected 6 values, got {len(joints_deg)}")
        j1, j2, j3, j4, j5, j6 = (math.radians(v) for v in joints_deg)
        r, z = self.arm_plane(j2, j3)
        rot = _rz(j1) @ _ry(j2 + j3) @ _rz(j4) @ _ry(j5) @ _rz(j6)
        m = np.eye(4)
        m[:3, :3] = rot
        m[:3, 3] = (r * math.cos(j1), r * math.sin(j1), z)
        m[:3, 3] += self.d6 * rot[:, 2]
        return m

    def flange_matrices(self, joints_deg: np.ndarray) -> np.ndarray:
        """4x4 flange transforms (M, 4, 4) of joint vectors (M, 6) in degrees, as :meth:`flange_matrix` computes
        one."""
        j = np.radians(np.asarray(joints_deg, dtype=float))
        j1, j2, j3 = j[:, 0], j[:, 1], j[:, 2]
        r = self.a1 + self.a2 * np.cos(j2) - self.a3 * np.cos(j2 + j3) + self.d4 * np.sin(j2 + j3)
        z = self.d1 - self.a2 * np.sin(j2) + self.a3 * np.sin(j2 + j3) + self.d4 * np.cos(j2 + j3)
        rot = _rz_many(j1) @ _ry_many(j2 + j3) @ _rz_many(j[:, 3]) @ _ry_many(j[:, 4]) @ _rz_many(j[:, 5])
        m = np.zeros((len(j), 4, 4))
        m[:, :3, :3] = rot
        m[:, :3, 3] = np.stack([r * np.cos(j1), r * np.sin(j1), z], axis=1) + self.d6 * rot[:, :, 2]
        m[:, 3, 3] = 1.0
        return m

    # -- inverse ---------------------------------------------------------------------------------------------
    def solutions_rad(self, m: np.ndarray, j4_hint: float, want: Configuration | None = None,
                      ) -> list[tuple[tuple[float, ...], Configuration]]:
        """The closed-form solutions (radians, each angle in (-pi, pi]) for a flange transform: all of them, or
        only those whose flags match ``want`` (a 0 in ``want`` accepts either choice; the singular wrist solution
        matches any).

        Raises ``RobotError(OUT_OF_REACH)`` when the wrist centre cannot be reached by any configuration.
        """
        a2, l3, beta = self.a2, self.l3, self.beta
        rot = m[:3, :3]
        wc = m[:3, 3] - self.d6 * rot[:, 2]
        rho = math.hypot(wc[0], wc[1])
        out: list[tuple[tuple[float, ...], Configuration]] = []
        reach_failed = True
        for shoulder in (1, -1):
            if rho < 1e-9:
                j1 = 0.0 if shoulder == 1 else math.pi  # on the J1 axis: any j1 works; keep it simple
            else:
                j1 = math.atan2(wc[1], wc[0]) if shoulder == 1 else math.atan2(-wc[1], -wc[0])
            u = shoulder * rho - self.a1
            v = wc[2] - self.d1
            d = (u * u + v * v - a2 ** 2 - l3 ** 2) / (2.0 * a2 * l3)
            if d > 1.0 + 1e-9 or d < -1.0 - 1e-9:
                continue
            reach_failed = False
            if want is not None and want.shoulder and shoulder != want.shoulder:
                continue
            d = max(-1.0, min(1.0, d))
            for elbow in (1, -1):
                if want is not None and want.elbow and elbow != want.elbow:
                    continue
                # |w|^2 = a2^2 + L^2 + 2 a2 L sin(j3 - beta); elbow +1 is the branch of home (j3 - beta > 90 deg).
                s = math.asin(d)
                j3 = (math.pi - s if elbow == 1 else s) + beta
                k = complex(a2, 0.0) + l3 * complex(math.cos(math.pi / 2 - j3 + beta), math.sin(math.pi / 2 - j3 + beta))
                j2 = math.atan2(k.imag, k.real) - math.atan2(v, u)
                j2, j3 = wrap_pi(j2), wrap_pi(j3)
                rw = _ry(-(j2 + j3)) @ _rz(-j1) @ rot
                sp = math.hypot(rw[2, 0], rw[2, 1])
                for wrist in (1, -1):
                    if want is not None and want.wrist and wrist != want.wrist and sp >= WRIST_SINGULAR_SIN:
                        continue
                    if sp < WRIST_SINGULAR_SIN and rw[2, 2] > 0:
                        # j5 ~ 0: J4 and J6 turn about (almost) the same axis, only j4 + j6 is well defined and the
                        # exact j4 swings with the slightest change. Keep j4 where it is and fit j5, j6 to the rest:
                        # Rz(-j4) rw = Ry(j5) Rz(j6) up to a tilt of at most sp about x.
                        if wrist == -1:
                            continue
                        fit = _rz(-j4_hint) @ rw
                        j4 = j4_hint
                        j5 = math.atan2(fit[0, 2], fit[2, 2])
                        j6 = math.atan2(fit[1, 0], fit[1, 1])
                        wrist = 0  # on the singularity: acceptable from either wrist configuration
                    elif sp < 1e-9:
                        # j5 ~ 180 (beyond the Viper's J5 limits, kept for completeness): only j6 - j4 is defined.
                        if wrist == -1:
                            continue
                        j5 = math.atan2(sp, rw[2, 2])
                        j4 = j4_hint
                        j6 = j4 - math.atan2(rw[1, 0], -rw[0, 0])
                        wrist = 0
                    else:
                        j5 = wrist * math.atan2(sp, rw[2, 2])
                        j4 = math.atan2(wrist * rw[1, 2], wrist * rw[0, 2])
                        j6 = math.atan2(wrist * rw[2, 1], -wrist * rw[2, 0])
                    sol = (j1, j2, j3, wrap_pi(j4), j5, wrap_pi(j6))
                    out.append((sol, Configuration(shoulder, elbow, wrist)))
        if reach_failed:
            raise RobotError(ErrorCode.OUT_OF_REACH,
                             f"location out of range (wrist centre {wc[0]:.1f},{wc[1]:.1f},{wc[2]:.1f})")
        return out

    def reach_reason(self, flange: np.ndarray) -> str | None:
        """Why no configuration reaches the flange transform ``flange``: ``"too_far"`` or ``"too_close"`` when the
        wrist centre lies outside the annulus the upper arm and forearm sweep (for both shoulder choices), None
        when it lies inside (then the configuration or the orientation is the reason)."""
        wc = flange[:3, 3] - self.d6 * flange[:3, 2]
        lo, hi = abs(self.a2 - self.l3), self.a2 + self.l3
        dists = [math.hypot(s * math.hypot(wc[0], wc[1]) - self.a1, wc[2] - self.d1) for s in (1, -1)]
        if any(lo <= d <= hi for d in dists):
            return None
        return "too_far" if min(dists) > hi else "too_close"

    def free_configuration(self, cur: Sequence[float]) -> Configuration:
        """The seed's configuration with 0 (either choice) for each flag within its band of a singularity."""
        j2, j3 = math.radians(cur[1]), math.radians(cur[2])
        r, _ = self.arm_plane(j2, j3)
        c3 = -math.cos(j3 - self.beta)
        s5 = math.sin(math.radians(cur[4]))
        return Configuration(
            shoulder=0 if abs(r) < SHOULDER_FREE_MM else (1 if r > 0 else -1),
            elbow=0 if abs(c3) < math.sin(math.radians(ELBOW_FREE_DEG)) else (1 if c3 > 0 else -1),
            wrist=0 if abs(s5) < math.sin(math.radians(WRIST_FREE_DEG)) else (1 if s5 > 0 else -1),
        )

    def inverse(self, pose: Pose, current_joints_deg: Sequence[float], tool: Pose = NULL, *,
                limits: JointLimits | None = None,
                jump: JumpLimit | None = DEFAULT_JUMP_LIMIT,
                config: ConfigRequest | None = None) -> tuple[float, ...]:
        """Inverse kinematics: joints (deg) that put the tool at ``pose``, continuing from ``current_joints_deg``.

        Choice of solution, as V+ does it and then safer:

        - The arm keeps the configuration of the seed ``current_joints_deg`` (LEFTY/RIGHTY, ABOVE/BELOW,
          FLIP/NOFLIP). A flag whose seed is within its band of the singularity that separates the two choices
          (:data:`WRIST_FREE_DEG`, :data:`SHOULDER_FREE_MM`, :data:`ELBOW_FREE_DEG`) accepts either choice, so the
          arm can pass through the singularity continuously instead of flipping to keep the sign.
        - Among the solutions allowed, each with every joint's +-360 deg equivalents inside ``limits`` (default:
          the model's), the one with the least total joint motion from the seed is taken.
        - On the wrist singularity (J5 = 0, within :data:`WRIST_SINGULAR_SIN`) only J4 + J6 is defined: J4 keeps
          the seed value and J6 takes the rotation (J5, J6 fitted; orientation error below ``WRIST_SINGULAR_SIN``
          rad). Elsewhere ``forward(inverse(pose))`` is ``pose`` to rounding.
        - The chosen solution is then checked against ``jump`` (see :class:`JumpLimit`): if a joint would move
          more than the Cartesian size of the move (seed pose to ``pose``) justifies, the target is refused with
          ``RobotError(JOINT_JUMP)`` and nothing moves. ``jump=None`` turns the check off.
        - ``config`` (V+ ``LEFTY`` ... ``SINGLE``, :class:`ConfigRequest`): each flag it sets replaces the seed's,
          so the arm changes configuration during this motion; a change asked for is not a jump (the jump check is
          skipped when the request differs from the seed's configuration). ``single`` keeps J6 within -180..180.

        Raises ``RobotError`` with ``OUT_OF_REACH`` when no allowed configuration reaches the pose,
        ``JOINT_LIMIT`` when its solution lies outside the joint limits, ``JOINT_JUMP`` as above,
        ``ILLEGAL_VALUE`` for a pose that is not finite.
        """
        if len(current_joints_deg) != 6:
            raise ValueError(f"current_joints_deg: expected 6 values, got {len(current_joints_deg)}")
        limits = self.limits if limits is None else limits
        cur = [float(v) for v in current_joints_deg]
        m = pose.to_matrix()
        if tool != NULL:
            m = m @ inverse_transform(tool.to_matrix())
        if not np.isfinite(m).all():
            raise RobotError(ErrorCode.ILLEGAL_VALUE, "location is not finite")
        want = self.free_configuration(cur)
        changing = False
        lo, hi = limits.min_deg, limits.max_deg
        if config is not None:
            # a change asked for (another configuration, SINGLE unwinding J6) is not a jump nobody asked for
            changing = config.changes(cur, self) or (config.single and abs(cur[5]) > 180.0 + 1e-9)
            want = Configuration(config.shoulder or want.shoulder, config.elbow or want.elbow,
                                 config.wrist or want.wrist)
            if config.single:
                lo, hi = lo[:5] + (max(lo[5], -180.0),), hi[:5] + (min(hi[5], 180.0),)
        sols = self.solutions_rad(m, math.radians(cur[3]), want)

        # J2 and J3 can exceed (-180, 180] within the limits, hence every joint's equivalents.
        wanted = [[math.degrees(a) for a in sol] for sol, c in sols if matches(c, want)]
        matched_config = bool(wanted)
        best = nearest_solution(wanted, cur, lo, hi)
        if best is None:
            if not matched_config:
                raise RobotError(ErrorCode.OUT_OF_REACH, "location out of range in the current configuration")
            # Report the limit the current-configuration solution breaks.
            for sol, c in sols:
                if matches(c, want):
                    deg = [math.degrees(a) for a in sol]
                    limits.check([d + 360.0 * round((cur[i] - d) / 360.0) for i, d in enumerate(deg)])
            raise RobotError(ErrorCode.JOINT_LIMIT, "no solution within the joint limits")
        if jump is not None and not changing:
            self._check_jump(best, cur, m, tool, limits, jump)
        return tuple(best)

    def _check_jump(self, sol: list[float], cur: list[float], m_flange: np.ndarray, tool: Pose,
                    limits: JointLimits, jump: JumpLimit) -> None:
        """Raise ``RobotError(JOINT_JUMP)`` when ``sol`` moves a joint more than ``jump`` allows for this move."""
        excess = jump_excess(self, sol, cur, m_flange, tool, jump)
        if excess is None:
            return
        worst, moved, distance, rotation, allowed = excess
        why = ""
        if worst in (3, 5) and abs(math.sin(math.radians(cur[4]))) < math.sin(math.radians(2 * WRIST_FREE_DEG)):
            why = "; wrist singularity"
        elif worst == 0 and abs(self.arm_plane(math.radians(cur[1]), math.radians(cur[2]))[0]) < 10 * SHOULDER_FREE_MM:
            why = "; wrist near J1 axis"
        else:
            near = sol[worst] + 360.0 * round((cur[worst] - sol[worst]) / 360.0)
            if abs(near - cur[worst]) < moved - 1e-6 and limits.violations(
                    [*cur[:worst], near, *cur[worst + 1:]]):
                why = f"; {near:.1f} is past the limit"
        # Short: the error ack carries at most 80 characters of text.
        raise RobotError(ErrorCode.JOINT_JUMP, f"J{worst + 1} would turn {moved:.1f} deg for {distance:.2f} "
                                               f"mm {rotation:.2f} deg (max {allowed:.1f}){why}")

    # -- description ---------------------------------------------------------------------------------------------
    @property
    def urdf_joints(self) -> tuple[UrdfJoint, ...]:
        """The chain, base to flange, as URDF joints: joint i turns by the V+ joint angle Ji (degrees).

        J1 turns about z at height d1; J2 about y at the shoulder (a1 out); J3 about y at the elbow (a2 along the
        upper arm); J4 about z at the a3 offset (-a3 along the forearm's x); J5 about y at the wrist centre (d4 up
        the forearm); J6 about z at the flange (d6 on). Ry(t)·(a2, 0, 0) = (a2 cos t, 0, -a2 sin t) is the upper
        arm of :meth:`arm_plane`, and Ry(j23)·(-a3, 0, d4) its forearm, so no extra fixed rotation is needed."""
        return (
            UrdfJoint("joint_1", "base_link", "link_1", (0.0, 0.0, self.d1), _Z),
            UrdfJoint("joint_2", "link_1", "link_2", (self.a1, 0.0, 0.0), _Y),
            UrdfJoint("joint_3", "link_2", "link_3", (self.a2, 0.0, 0.0), _Y),
            UrdfJoint("joint_4", "link_3", "link_4", (-self.a3, 0.0, 0.0), _Z),
            UrdfJoint("joint_5", "link_4", "link_5", (0.0, 0.0, self.d4), _Y),
            UrdfJoint("joint_6", "link_5", "flange", (0.0, 0.0, self.d6), _Z),
        )

    def describe(self) -> str:
        """The constants, for the URDF's comment."""
        return (f"a1={self.a1:g} d1={self.d1:g} a2={self.a2:g} a3={self.a3:g} d4={self.d4:g} d6={self.d6:g} mm")


VIPER_S850 = Viper("viper-s850", a1=75.0, d1=335.0, a2=365.0, a3=90.0, d4=405.0, d6=80.0,
                   limits=JointLimits((-170.0, -190.0, -29.0, -190.0, -120.0, -360.0),
                                      (170.0, 45.0, 256.0, 190.0, 120.0, 360.0)),
                   max_speed_deg_s=(250.0, 250.0, 250.0, 375.0, 375.0, 600.0))
"""The paper's arm (ViSP ``vpViper850``; joint speeds from ARTE)."""

VIPER_S650 = Viper("viper-s650", a1=75.0, d1=335.0, a2=270.0, a3=90.0, d4=295.0, d6=80.0,
                   limits=JointLimits((-170.0, -190.0, -29.0, -190.0, -120.0, -360.0),
                                      (170.0, 45.0, 256.0, 190.0, 120.0, 360.0)),
                   max_speed_deg_s=(328.0, 300.0, 375.0, 375.0, 375.0, 600.0))
"""ViSP ``vpViper650`` (its d6 adds a 101.6 mm tool changer; the flange itself is d6 = 80, as in ARTE's
``VIPER_s650``); joint speeds from ARTE's ``VIPER_s650``."""

__all__ = ["ELBOW_FREE_DEG", "SHOULDER_FREE_MM", "VIPER_S650", "VIPER_S850", "WRIST_FREE_DEG",
           "WRIST_SINGULAR_SIN", "Viper"]
