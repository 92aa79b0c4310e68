"""The arm under test in the conformance suite: joint values, poses and speeds taken from the robot model, so one
test means the same thing on a Viper (six revolute joints) and a Cobra (four axes, J3 a prismatic quill in mm, the
tool pointing down).

Joint targets are the model's home with some joints changed (J1 turns the whole arm about the base on both
families); Cartesian targets lie about a work point in front of the arm, tool pointing down, reachable from home in
its configuration on every model; speeds are scaled so J1 turns at the Viper s850's rate, so a motion takes about
as long on every model and the suite's time bounds keep their meaning.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from aioadept.geometry import Pose
from aioadept.robots import DEFAULT_MODEL, MODELS, RobotModel, model

REFERENCE_J1_DEG_S = MODELS[DEFAULT_MODEL].max_speed_deg_s[0]
"""J1's speed at 100 % on the suite's reference arm (the Viper s850): the rate :meth:`Arm.speed` keeps."""

WORK_POINT = {"viper": (400.0, 0.0, 400.0), "scara": (400.0, 0.0, 250.0)}
"""Per family, a point in front of the arm (mm, base frame) with room around it: 150 mm either way in y, 100 mm up
(and 80 down on a Viper; the quill has 70 mm below it on a Cobra), reachable with the tool pointing down."""

LIMIT_MARGIN_DEG = 5.0
"""How far inside its limits :meth:`Arm.j1` keeps J1."""


@dataclass(frozen=True)
class Arm:
    """One robot model as the conformance tests drive it over the wire."""

    m: RobotModel

    @classmethod
    def named(cls, name: str) -> Arm:
        return cls(model(name))

    @property
    def name(self) -> str:
        return self.m.name

    @property
    def is_scara(self) -> bool:
        return self.m.family == "scara"

    @property
    def home(self) -> tuple[float, ...]:
        return tuple(self.m.home_deg)

    @property
    def last(self) -> int:
        """Index of the last joint (J6 on a Viper, J4 on a Cobra): the flange's own turn."""
        return self.m.dof - 1

    # -- joints ------------------------------------------------------------------------------------------------
    def wire(self, joints: Sequence[float]) -> str:
        """Joint values as the protocol's six (a SCARA's four, then zeros), 3 decimals."""
        return ",".join(f"{v:.3f}" for v in self.six(joints))

    def six(self, joints: Sequence[float]) -> list[float]:
        return [float(v) for v in joints] + [0.0] * (6 - len(joints))

    @property
    def home_wire(self) -> str:
        return self.wire(self.home)

    def j1(self, deg: float) -> tuple[float, ...]:
        """Home with J1 at ``deg`` (J1 is 0 at home on every model), kept inside J1's limits."""
        lo, hi = self.m.limits.min_deg[0] + LIMIT_MARGIN_DEG, self.m.limits.max_deg[0] - LIMIT_MARGIN_DEG
        q = list(self.home)
        q[0] = min(hi, max(lo, deg))
        return tuple(q)

    def j1_wire(self, deg: float) -> str:
        return self.wire(self.j1(deg))

    def rel_last(self, value: float) -> str:
        """A relative joint move of only the last joint by ``value``, as the protocol's six."""
        d = [0.0] * self.m.dof
        d[self.last] = value
        return self.wire(d)

    def with_joint(self, index: int, value: float, joints: Sequence[float] | None = None) -> tuple[float, ...]:
        """``joints`` (default: home) with joint ``index`` (0-based) set to ``value``, unchecked."""
        q = list(self.home if joints is None else joints)
        q[index] = value
        return tuple(q)

    def with_last(self, value: float, joints: Sequence[float] | None = None) -> tuple[float, ...]:
        return self.with_joint(self.last, value, joints)

    # -- poses -------------------------------------------------------------------------------------------------
    def pose(self, joints: Sequence[float] | str) -> Pose:
        """The flange pose of joint values (a tuple of the model's joints, or their wire text)."""
        if isinstance(joints, str):
            joints = [float(v) for v in joints.split(",")][: self.m.dof]
        return self.m.forward(joints)

    @staticmethod
    def pose_wire(p: Pose, *extra: float) -> str:
        """A pose (and any further numbers) as the protocol's text, 3 decimals."""
        return ",".join(f"{v:.3f}" for v in (*p.as_tuple(), *extra))

    @property
    def home_pose(self) -> Pose:
        return self.pose(self.home)

    def at(self, dx: float = 0.0, dy: float = 0.0, dz: float = 0.0, roll: float = 0.0) -> Pose:
        """A pose ``(dx, dy, dz)`` mm from the model's work point, tool pointing down, turned ``roll`` deg about
        its axis."""
        x, y, z = WORK_POINT[self.m.family]
        return Pose(x + dx, y + dy, z + dz, 0.0, 180.0, roll)

    # -- speed -------------------------------------------------------------------------------------------------
    def speed(self, pct: float) -> int:
        """The ``set_speed`` percentage at which J1 turns as fast as the Viper s850's does at ``pct`` %."""
        return max(1, round(pct * REFERENCE_J1_DEG_S / self.m.max_speed_deg_s[0]))


__all__ = ["Arm", "REFERENCE_J1_DEG_S", "WORK_POINT"]
