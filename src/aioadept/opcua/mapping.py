"""What the OPC UA server shows, decided without an OPC UA library: a robot.state sample and a ``status`` answer
turned into the values of the Robotics model's variables, each with its quality and source time.

Pure and synchronous, so it is tested without a server. :class:`RobotView` keeps one robot's latest sample, the one
before it (for the axes' speeds) and its latest status; :meth:`RobotView.readings` gives every live variable's
:class:`Reading` at a given moment, so a stream that has stalled turns its values Uncertain by itself.
The asyncua side (:mod:`aioadept.opcua.server`) only writes these readings into the nodes their keys name.

Units are the Robotics specification's (OPC 40010-1, AxisType: ActualPosition, ActualSpeed): degrees and degrees per
second for a rotary axis, millimetres and millimetres per second for a linear one (a SCARA's quill, J3), as UNECE
codes in an ``EUInformation`` (:data:`DEGREE`, :data:`DEGREE_PER_SECOND`, :data:`MILLIMETRE`,
:data:`MILLIMETRE_PER_SECOND`). Which axes a robot has, and which of them slide, is its model's
(:func:`identity_of_model`, :mod:`aioadept.robots`).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Any

__all__ = ["DEGREE", "DEGREE_CELSIUS", "DEGREE_PER_SECOND", "DI_NS", "IA_NS", "INSTANCE_NS", "MILLIMETRE",
           "MILLIMETRE_PER_SECOND", "NODESETS", "ROBOTICS_NS", "STALE_AFTER_S", "AxisMotionProfile", "EngineeringUnit",
           "Identity", "MotionDeviceCategory", "OperationalMode", "Quality", "Reading", "RobotView", "identity_of_model",
           "model_title", "unece_unit_id"]

DI_NS = "http://opcfoundation.org/UA/DI/"
IA_NS = "http://opcfoundation.org/UA/IA/"
ROBOTICS_NS = "http://opcfoundation.org/UA/Robotics/"
INSTANCE_NS = "urn:aioadept:opcua:cell"
"""The namespace of this server's own nodes: the MotionDeviceSystem and everything under it."""
NODESETS = ("Opc.Ua.Di.NodeSet2.xml", "Opc.Ua.IA.NodeSet2.xml", "Opc.Ua.Robotics.NodeSet2.xml")
"""The package's nodesets, in the order they must be loaded (each requires the ones before it)."""

STALE_AFTER_S = 0.5
"""A state stream silent this long is stalled: its values turn Uncertain (checked every tenth of a second by the
server, so within 0.6 s: the issue's bound is one second)."""


class MotionDeviceCategory(enum.IntEnum):
    """Robotics' MotionDeviceCategoryEnumeration."""
    OTHER = 0
    ARTICULATED_ROBOT = 1
    SCARA_ROBOT = 2
    CARTESIAN_ROBOT = 3
    SPHERICAL_ROBOT = 4
    PARALLEL_ROBOT = 5
    CYLINDRICAL_ROBOT = 6


class AxisMotionProfile(enum.IntEnum):
    """Robotics' AxisMotionProfileEnumeration."""
    OTHER = 0
    ROTARY = 1
    ROTARY_ENDLESS = 2
    LINEAR = 3
    LINEAR_ENDLESS = 4


class OperationalMode(enum.IntEnum):
    """Robotics' OperationalModeEnumeration (no V+ answer says which: the variable stays Bad)."""
    OTHER = 0
    MANUAL_REDUCED_SPEED = 1
    MANUAL_HIGH_SPEED = 2
    AUTOMATIC = 3
    AUTOMATIC_EXTERNAL = 4


def unece_unit_id(code: str) -> int:
    """The ``UnitId`` of a UNECE Recommendation 20 common code, as OPC UA Part 8 packs it (each character's byte,
    first character highest): ``"DD"`` (degree) is 0x4444."""
    if not 1 <= len(code) <= 3 or not code.isascii() or not code.isalnum():
        raise ValueError(f"UNECE code {code!r}: expected 1-3 letters or digits")
    n = 0
    for ch in code:
        n = (n << 8) | ord(ch)
    return n


@dataclass(frozen=True, slots=True)
class EngineeringUnit:
    """An ``EUInformation``: the UNECE code, the symbol shown, the name."""
    code: str
    symbol: str
    name: str

    @property
    def unit_id(self) -> int:
        return unece_unit_id(self.code)


DEGREE = EngineeringUnit("DD", "°", "degree")
DEGREE_PER_SECOND = EngineeringUnit("E96", "°/s", "degree per second")
DEGREE_CELSIUS = EngineeringUnit("CEL", "°C", "degree Celsius")
MILLIMETRE = EngineeringUnit("MMT", "mm", "millimetre")
MILLIMETRE_PER_SECOND = EngineeringUnit("C16", "mm/s", "millimetre per second")


class Quality(enum.Enum):
    """How good a value is; the server writes each as an OPC UA status code (docs/opcua.md, "Quality")."""
    GOOD = "Good"
    STALE = "UncertainNoCommunicationLastUsableValue"
    """The source stopped: this is the last value it gave."""
    WAITING = "BadWaitingForInitialData"
    """Nothing came from the source yet."""
    NOT_EXPOSED = "BadNotSupported"
    """Neither the controller (V+) nor the cell's configuration says this: no value is made up."""


@dataclass(frozen=True, slots=True)
class Reading:
    """One variable's value: ``value`` (None when there is none), its quality, and the source time (epoch s, the
    robot's own clock where it has one; None: none)."""
    value: Any
    quality: Quality
    source_time_s: float | None = None


NOT_EXPOSED = Reading(None, Quality.NOT_EXPOSED)


@dataclass(frozen=True, slots=True)
class Identity:
    """A robot as the cell knows it. An empty text or a None category is not known: its property is Bad, never a
    made-up value. The manufacturer is the one every V+ controller has; the arm's model and kind are the cell's to
    say (``aioadept sim`` simulates a Viper s850, an articulated robot)."""
    name: str = "Robot1"
    manufacturer: str = "Omron Adept Technologies"
    model: str = ""
    serial_number: str = ""
    product_code: str = ""
    category: MotionDeviceCategory | None = None
    axes: int = 6
    controller_model: str = ""
    controller_serial_number: str = ""
    linear: tuple[bool, ...] = ()
    """Per axis, whether it slides (LINEAR, mm) rather than turns (ROTARY, degrees); () is every axis rotary."""
    axis_names: tuple[str, ...] = ()
    """Per axis, the model's joint name (its DisplayName; the URDF's and ROS's ``joint_1`` ...); (): ``Axis<i>``."""

    def __post_init__(self) -> None:
        if self.axes < 1 or len(self.linear) not in (0, self.axes) or len(self.axis_names) not in (0, self.axes):
            raise ValueError(f"{self.name}: {self.axes} axes, {len(self.linear)} linear flags, "
                             f"{len(self.axis_names)} axis names: expected one flag and one name per axis")

    def text(self, value: str) -> Reading:
        return Reading(value, Quality.GOOD) if value else NOT_EXPOSED

    def is_linear(self, axis: int) -> bool:
        """Whether axis ``axis`` (from 1) slides."""
        return bool(self.linear) and self.linear[axis - 1]

    def profile(self, axis: int) -> AxisMotionProfile:
        """Axis ``axis``'s MotionProfile (from 1): a V+ joint has stops at its limits, so never the ENDLESS kinds."""
        return AxisMotionProfile.LINEAR if self.is_linear(axis) else AxisMotionProfile.ROTARY

    def units(self, axis: int) -> tuple[EngineeringUnit, EngineeringUnit]:
        """Axis ``axis``'s position and speed units (from 1)."""
        return (MILLIMETRE, MILLIMETRE_PER_SECOND) if self.is_linear(axis) else (DEGREE, DEGREE_PER_SECOND)


_CATEGORY_OF_FAMILY = {"viper": MotionDeviceCategory.ARTICULATED_ROBOT, "scara": MotionDeviceCategory.SCARA_ROBOT}


def model_title(model_name: str) -> str:
    """A registry name as people write it: ``"cobra-s600"`` is ``"Cobra s600"``."""
    family, _, size = model_name.partition("-")
    return f"{family.capitalize()} {size}".strip()


def identity_of_model(model_name: str, **identity: Any) -> Identity:
    """The :class:`Identity` of a robot of model ``model_name`` (:func:`aioadept.robots.model`; ValueError naming the
    known ones): its axes, which of them slide and their names, and, unless ``identity`` gives them, its Model text
    (:func:`model_title`) and MotionDeviceCategory (SCARA_ROBOT for a Cobra, ARTICULATED_ROBOT for a Viper).
    ``identity``: the other :class:`Identity` fields."""
    from aioadept.robots import model

    m = model(model_name)
    identity.setdefault("model", model_title(m.name))
    identity.setdefault("category", _CATEGORY_OF_FAMILY[m.family])
    return Identity(axes=m.dof, linear=tuple(m.prismatic), axis_names=tuple(j.name for j in m.urdf_joints),
                    **identity)


def _key_axis(i: int, name: str) -> tuple[str, int, str]:
    return ("axis", i, name)


class RobotView:
    """One robot's live values: :meth:`on_state` with each robot.state sample (its arrival time on a monotonic
    clock), :meth:`on_status` with each ``status`` answer (or None when asking failed), :meth:`on_hello` with the
    server's ``hello``; :meth:`readings` at a moment gives every live variable's :class:`Reading`, keyed as
    ``("axis", i, "ActualPosition")``, ``("axis", i, "ActualSpeed")`` (i from 1), ``("device", "SpeedOverride")``,
    ``("safety", "EmergencyStop" | "ProtectiveStop" | "OperationalMode")``, ``("task", "TaskProgramName" |
    "TaskProgramLoaded")``, ``("software", "Model" | "SoftwareRevision")``."""

    def __init__(self, identity: Identity = Identity(), *, stale_after_s: float = STALE_AFTER_S) -> None:
        if not (math.isfinite(stale_after_s) and stale_after_s > 0):
            raise ValueError(f"stale_after_s: {stale_after_s!r} is not a number of seconds > 0")
        self.identity = identity
        self.stale_after_s = stale_after_s
        self._state: Any = None
        self._arrived = -math.inf
        self._speeds: tuple[float, ...] | None = None
        self._status: Any = None
        self._status_ok = False
        self._status_time: float | None = None
        self._hello: tuple[int | None, str] | None = None
        self._hello_ok = False

    def on_state(self, state: Any, arrived_s: float) -> None:
        """A robot.state sample (``t_s``, ``wall_time_s``, ``joints_deg``, ``speed_pct``), arrived at ``arrived_s``
        (monotonic). The axes' speeds come from this sample and the one before it on the robot's own clock, and
        only while the stream runs: after a stall there is no speed until the second sample."""
        prev = self._state
        if len(state.joints_deg) != self.identity.axes:
            raise ValueError(f"robot.state has {len(state.joints_deg)} joints, {self.identity.name} has "
                             f"{self.identity.axes} axes")
        if prev is not None and not self.stale(arrived_s) and state.t_s > prev.t_s:
            dt = state.t_s - prev.t_s
            self._speeds = tuple((a - b) / dt for a, b in zip(state.joints_deg, prev.joints_deg, strict=True))
        elif prev is None or self.stale(arrived_s):
            self._speeds = None
        self._state = state
        self._arrived = arrived_s

    def on_status(self, status: Any, now_s: float | None = None) -> None:
        """A ``status`` answer (:class:`aioadept.protocol.robotstatus.RobotStatus`), or None: the last ask failed
        (the values it gave turn Uncertain)."""
        if status is None:
            self._status_ok = False
            return
        self._status, self._status_ok, self._status_time = status, True, now_s

    def on_hello(self, hello: tuple[int | None, str] | None) -> None:
        """The server's ``(protocol_version, server_name)``, or None: the connection to it is lost."""
        if hello is None:
            self._hello_ok = False
            return
        self._hello, self._hello_ok = hello, True

    def stale(self, now_s: float) -> bool:
        """True when no sample came in the last ``stale_after_s`` (or none ever)."""
        return now_s - self._arrived > self.stale_after_s

    def _live(self, value: Any, now_s: float) -> Reading:
        st = self._state
        if st is None:
            return Reading(None, Quality.WAITING)
        return Reading(value, Quality.STALE if self.stale(now_s) else Quality.GOOD, st.wall_time_s)

    def readings(self, now_s: float) -> dict[tuple, Reading]:
        """Every live variable's reading at ``now_s`` (the monotonic clock of :meth:`on_state`)."""
        out: dict[tuple, Reading] = {}
        st = self._state
        for i in range(1, self.identity.axes + 1):
            out[_key_axis(i, "ActualPosition")] = self._live(st and st.joints_deg[i - 1], now_s)
            if st is not None and self._speeds is None:
                out[_key_axis(i, "ActualSpeed")] = Reading(None, Quality.STALE if self.stale(now_s)
                                                           else Quality.WAITING, st.wall_time_s)
            else:
                out[_key_axis(i, "ActualSpeed")] = self._live(self._speeds and self._speeds[i - 1], now_s)
        out[("device", "SpeedOverride")] = self._live(st and float(st.speed_pct), now_s)
        out.update(self._safety())
        out.update(self._software())
        return out

    def _from_status(self, value: Any) -> Reading:
        if self._status is None:
            return Reading(None, Quality.WAITING)
        if value is None:
            return NOT_EXPOSED
        return Reading(value, Quality.GOOD if self._status_ok else Quality.STALE, self._status_time)

    def _safety(self) -> dict[tuple, Reading]:
        st = self._status
        # V+'s status says E-stop (es=, where the server knows it); neither a protective stop apart from it nor the
        # operating mode (the controller's keyswitch) is in any answer: those stay Bad, never a guess.
        return {("safety", "EmergencyStop"): self._from_status(st.estop if st is not None else None),
                ("safety", "ProtectiveStop"): NOT_EXPOSED,
                ("safety", "OperationalMode"): NOT_EXPOSED}

    def _software(self) -> dict[tuple, Reading]:
        if self._hello is None:
            waiting = Reading(None, Quality.WAITING)
            return {("software", "Model"): waiting, ("software", "SoftwareRevision"): waiting,
                    ("task", "TaskProgramName"): waiting, ("task", "TaskProgramLoaded"): waiting}
        version, name = self._hello
        q = Quality.GOOD if self._hello_ok else Quality.STALE
        return {("software", "Model"): Reading(name, q) if name else NOT_EXPOSED,
                ("software", "SoftwareRevision"): Reading(str(version), q) if version is not None else NOT_EXPOSED,
                # The program the controller runs for us is the robot server that answered hello.
                ("task", "TaskProgramName"): Reading(name, q) if name else NOT_EXPOSED,
                ("task", "TaskProgramLoaded"): Reading(True, q)}

