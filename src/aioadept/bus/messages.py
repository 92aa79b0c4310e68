"""Plain Python values <-> Protobuf bytes: the only place where the bus touches generated code.

Everything inside aioadept handles events, images and robot states as frozen dataclasses and dicts; this module turns
them into the EPypes wire format (``epypes.proto``, wire-compatible with EPypes nodes) or our own
(``aioadept.proto``) and back. Protobuf's ``DecodeError`` and missing required fields become :class:`BusError`;
values the schema cannot carry become :class:`BusEncodeError` before anything is sent.

Attribute typing follows EPypes' ``add_attribute``/``get_attributes_dict``::

    str   <-> STRING (str_val)
    float <-> DOUBLE (double_val)      numpy floats too
    int   <-> INT    (int_val, int32)  numpy ints too; outside int32 -> BusEncodeError
    bool  -> BusEncodeError            EPypes has no BOOL; True would come back as 1. Pass int(flag).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Union

from google.protobuf.message import DecodeError, EncodeError

from aioadept.bus import aioadept_pb2, epypes_pb2
from aioadept.errors import BusEncodeError, BusError
from aioadept.geometry import Pose

__all__ = [
    "AttributeValue",
    "EventMessage",
    "ImageMessage",
    "RobotState",
    "SignalEvent",
    "WorldState",
    "ROBOT_STATE_TOPIC",
    "WORLD_STATE_TOPIC",
    "VISION_REQUEST",
    "INT32_MIN",
    "INT32_MAX",
    "attributes_to_pb",
    "attributes_from_pb",
    "encode_event",
    "decode_event",
    "encode_image",
    "decode_image",
    "event_to_pb",
    "event_from_pb",
]

AttributeValue = Union[str, float, int]

INT32_MIN = -(2**31)
INT32_MAX = 2**31 - 1

_STRING = epypes_pb2.Attribute.STRING
_DOUBLE = epypes_pb2.Attribute.DOUBLE
_INT = epypes_pb2.Attribute.INT


# ---------------------------------------------------------------------------------------------------- attributes

def _fill_attribute(attr: epypes_pb2.Attribute, key: str, value: Any) -> None:
    if not isinstance(key, str):
        raise BusEncodeError(f"attribute key must be str, got {type(key).__name__}", key=key, value=value)
    attr.key = key
    # Exact type checks first: they are the common case and cheaper than the numbers ABCs.
    tp = type(value)
    if tp is str:
        attr.type = _STRING
        attr.str_val = value
    elif tp is float:
        attr.type = _DOUBLE
        attr.double_val = value
    elif tp is int:
        _fill_int(attr, key, value)
    elif tp is bool or (hasattr(value, "dtype") and getattr(value.dtype, "kind", "") == "b"):
        raise BusEncodeError(f"attribute {key!r}: bool has no EPypes type; pass int(value)", key=key, value=value)
    elif isinstance(value, str):
        attr.type = _STRING
        attr.str_val = str(value)
    elif isinstance(value, numbers.Integral):
        _fill_int(attr, key, int(value))
    elif isinstance(value, numbers.Real):
        attr.type = _DOUBLE
        attr.double_val = float(value)
    else:
        raise BusEncodeError(
            f"attribute {key!r}: type {tp.__name__} has no EPypes type (str, float, int)", key=key, value=value)


def _fill_int(attr: epypes_pb2.Attribute, key: str, value: int) -> None:
    if not INT32_MIN <= value <= INT32_MAX:
        raise BusEncodeError(f"attribute {key!r}: {value} is outside int32; send it as float or str",
                             key=key, value=value)
    attr.type = _INT
    attr.int_val = value


def attributes_to_pb(attributes: Mapping[str, Any] | None, out: epypes_pb2.AttributeList) -> None:
    """Append ``attributes`` (key -> str/float/int) to the Protobuf ``AttributeList`` ``out``.

    Raises :class:`BusEncodeError` for a value the schema cannot carry.
    """
    if not attributes:
        return
    entries = out.entries
    for key, value in attributes.items():
        _fill_attribute(entries.add(), key, value)


def attributes_from_pb(attribute_list: epypes_pb2.AttributeList) -> dict[str, AttributeValue]:
    """The attributes of a Protobuf ``AttributeList`` as a dict; a repeated key keeps its last value (as EPypes)."""
    out: dict[str, AttributeValue] = {}
    for entry in attribute_list.entries:
        t = entry.type
        if t == _DOUBLE:
            out[entry.key] = entry.double_val
        elif t == _STRING:
            out[entry.key] = entry.str_val
        else:  # EPypes' get_attributes_dict reads int_val for anything that is not STRING/DOUBLE.
            out[entry.key] = entry.int_val
    return out


def _parse(pb: Any, data: bytes, what: str) -> Any:
    """``pb`` (an empty message) filled from ``data``; garbage or missing required fields raise :class:`BusError`
    saying the bytes are not ``what`` (e.g. "an EPypes Event")."""
    try:
        pb.ParseFromString(data)
    except (DecodeError, EncodeError) as exc:  # EncodeError is not expected here, but keep protobuf types inside
        raise BusError(f"not {what} ({len(data)} bytes): {exc}") from exc
    # The upb runtime parses proto2 messages with missing required fields without complaint (b"" parses as an
    # empty Event), so we check explicitly: an Event without a type is not an EPypes Event.
    if not pb.IsInitialized():
        missing = ", ".join(pb.FindInitializationErrors())
        raise BusError(f"{pb.DESCRIPTOR.full_name} ({len(data)} bytes) lacks required fields: {missing}")
    return pb


# ---------------------------------------------------------------------------------------------------- events

@dataclass(frozen=True, slots=True)
class EventMessage:
    """An EPypes ``Event`` as a plain value: ``event_type``, optional ``id`` and attributes (str/float/int)."""

    event_type: str
    id: str | None = None
    attributes: dict[str, AttributeValue] = field(default_factory=dict)

    def to_bytes(self) -> bytes:
        return encode_event(self.event_type, self.id, self.attributes)

    @classmethod
    def from_bytes(cls, data: bytes) -> EventMessage:
        event_type, event_id, attributes = decode_event(data)
        return cls(event_type, event_id, attributes)


def event_to_pb(event_type: str, event_id: str | None = None,
                attributes: Mapping[str, Any] | None = None) -> epypes_pb2.Event:
    """Build a Protobuf ``Event`` (for code that needs the message object itself, e.g. the paper's API)."""
    if not isinstance(event_type, str):
        raise BusEncodeError(f"event type must be str, got {type(event_type).__name__}", value=event_type)
    pb = epypes_pb2.Event(type=event_type)
    if event_id is not None:
        pb.id = event_id
    if attributes:
        attributes_to_pb(attributes, pb.attributes)
    return pb


def event_from_pb(pb: epypes_pb2.Event) -> tuple[str, str | None, dict[str, AttributeValue]]:
    """``(type, id or None, attributes)`` of a Protobuf ``Event``."""
    return (pb.type, pb.id if pb.HasField("id") else None, attributes_from_pb(pb.attributes))


def encode_event(event_type: str, event_id: str | None = None, attributes: Mapping[str, Any] | None = None) -> bytes:
    """Serialise an EPypes ``Event``. Raises :class:`BusEncodeError` for an attribute the schema cannot carry."""
    return event_to_pb(event_type, event_id, attributes).SerializeToString()


def decode_event(data: bytes) -> tuple[str, str | None, dict[str, AttributeValue]]:
    """Parse EPypes ``Event`` bytes into ``(type, id or None, attributes)``; garbage raises :class:`BusError`."""
    return event_from_pb(_parse(epypes_pb2.Event(), data, "an EPypes Event"))


# ---------------------------------------------------------------------------------------------------- images

@dataclass(frozen=True, slots=True)
class ImageMessage:
    """An EPypes ``Image``: encoded image ``data`` (e.g. PNG bytes or raw pixels), optional id, format, attributes.

    ``format`` is free text in EPypes (whose nodes put ``cv2.imencode`` output in ``bytes``). aioadept writes
    ``"png"``/``"jpg"`` for encoded images and ``"mono8:WxH"`` / ``"bgr8:WxH"`` for raw 8-bit pixels; see
    :meth:`from_array` and :meth:`to_array`.
    """

    data: bytes
    id: str | None = None
    format: str | None = None
    attributes: dict[str, AttributeValue] = field(default_factory=dict)

    def to_bytes(self) -> bytes:
        return encode_image(self.data, id=self.id, format=self.format, attributes=self.attributes)

    @classmethod
    def from_bytes(cls, data: bytes) -> ImageMessage:
        return decode_image(data)

    @classmethod
    def from_array(cls, image: Any, *, encoding: str = "raw", id: str | None = None,
                   attributes: Mapping[str, Any] | None = None) -> ImageMessage:
        """An 8-bit mono (H x W) or BGR (H x W x 3) numpy image as a message.

        ``encoding="raw"`` stores the pixels (format ``mono8:WxH`` / ``bgr8:WxH``: no codec cost, the choice on one
        machine); ``"png"`` or ``"jpg"`` encode with OpenCV (smaller, and what EPypes nodes decode with
        ``cv2.imdecode``). Raises :class:`BusEncodeError` for other shapes/dtypes or encodings.
        """
        import numpy as np

        arr = np.asarray(image)
        if arr.dtype != np.uint8 or not (arr.ndim == 2 or (arr.ndim == 3 and arr.shape[2] == 3)):
            raise BusEncodeError(f"image must be uint8 HxW or HxWx3, got {arr.dtype} {arr.shape}")
        attrs = dict(attributes or {})
        if encoding == "raw":
            kind = "mono8" if arr.ndim == 2 else "bgr8"
            return cls(np.ascontiguousarray(arr).tobytes(), id, f"{kind}:{arr.shape[1]}x{arr.shape[0]}", attrs)
        if encoding in ("png", "jpg"):
            import cv2

            ok, buf = cv2.imencode("." + encoding, arr)
            if not ok:
                raise BusEncodeError(f"OpenCV could not encode the image as {encoding}")
            return cls(buf.tobytes(), id, encoding, attrs)
        raise BusEncodeError(f"unknown image encoding {encoding!r}; use 'raw', 'png' or 'jpg'")

    def to_array(self) -> Any:
        """The pixels as a numpy array: raw ``mono8``/``bgr8`` formats are reshaped, anything else is decoded with
        ``cv2.imdecode`` (as EPypes nodes do). Raises :class:`BusError` if the data does not fit its format."""
        import numpy as np

        fmt = self.format or ""
        kind, _, size = fmt.partition(":")
        if kind in ("mono8", "bgr8") and size:
            try:
                w, h = (int(v) for v in size.split("x"))
            except ValueError:
                raise BusError(f"bad raw image format {fmt!r}") from None
            channels = 1 if kind == "mono8" else 3
            if len(self.data) != w * h * channels:
                raise BusError(f"{fmt}: expected {w * h * channels} bytes, got {len(self.data)}")
            shape = (h, w) if channels == 1 else (h, w, 3)
            return np.frombuffer(self.data, dtype=np.uint8).reshape(shape)
        import cv2

        img = cv2.imdecode(np.frombuffer(self.data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise BusError(f"image data ({len(self.data)} bytes, format {fmt!r}) does not decode")
        return img


def encode_image(data: bytes, *, id: str | None = None, format: str | None = None,
                 attributes: Mapping[str, Any] | None = None) -> bytes:
    """Serialise an EPypes ``Image`` holding ``data``. Raises :class:`BusEncodeError` for bad attributes."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise BusEncodeError(f"image data must be bytes, got {type(data).__name__}")
    pb = epypes_pb2.Image(bytes=bytes(data))
    if id is not None:
        pb.id = id
    if format is not None:
        pb.format = format
    if attributes:
        attributes_to_pb(attributes, pb.attributes)
    return pb.SerializeToString()


def decode_image(data: bytes) -> ImageMessage:
    """Parse EPypes ``Image`` bytes; garbage raises :class:`BusError`."""
    pb = _parse(epypes_pb2.Image(), data, "an EPypes Image")
    return ImageMessage(
        data=pb.bytes,
        id=pb.id if pb.HasField("id") else None,
        format=pb.format if pb.HasField("format") else None,
        attributes=attributes_from_pb(pb.attributes),
    )


# ---------------------------------------------------------------------------------------------------- robot state

VISION_REQUEST = "VisionRequest"
"""The event type of a vision request (the paper's MCN, EPypes); the one type the vision node serves."""

ROBOT_STATE_TOPIC = b"robot.state"
"""Topic frame of the robot state stream (docs/interfaces.md)."""


@dataclass(frozen=True, slots=True)
class SignalEvent:
    """One change of one digital signal in a :class:`RobotState`: at server time ``t_s``, ``signal`` became ``on``."""

    t_s: float
    signal: int
    on: bool


@dataclass(frozen=True, slots=True)
class RobotState:
    """One sample of the robot's state, as the sim publishes it on ``robot.state`` (docs/interfaces.md).

    ``t_s`` is the robot server clock (s since server start), ``wall_time_s`` the epoch time of the sample,
    ``joints_deg`` the six joint angles, ``pose`` the flange/tool in world (mm, degrees), ``speed_pct`` the program
    speed (0..100).
    """

    t_s: float
    wall_time_s: float
    joints_deg: tuple[float, ...]
    pose: Pose
    in_motion: bool = False
    speed_pct: int = 100
    air: bool = False
    outputs_on: tuple[int, ...] = ()
    """Digital I/O and the hand: the signal numbers that are on, by kind, the gripper's state ("" if unknown),
    and each signal change since the previous sample (docs/sim.md)."""
    inputs_on: tuple[int, ...] = ()
    soft_on: tuple[int, ...] = ()
    hand: str = ""
    changes: tuple[SignalEvent, ...] = ()

    def __post_init__(self) -> None:
        # Normalise so that a state equals its own round trip (ints in, floats back).
        object.__setattr__(self, "joints_deg", tuple(float(j) for j in self.joints_deg))
        for name in ("outputs_on", "inputs_on", "soft_on"):
            object.__setattr__(self, name, tuple(int(n) for n in getattr(self, name)))
        object.__setattr__(self, "changes", tuple(self.changes))

    def to_bytes(self) -> bytes:
        """Serialise as ``aioadept.RobotState``; non-finite times or a speed outside int32 raise BusEncodeError."""
        if not (math.isfinite(self.t_s) and math.isfinite(self.wall_time_s)):
            raise BusEncodeError("robot state times must be finite", value=(self.t_s, self.wall_time_s))
        speed = int(self.speed_pct)
        if not INT32_MIN <= speed <= INT32_MAX:
            raise BusEncodeError("speed_pct outside int32", key="speed_pct", value=self.speed_pct)
        p = self.pose
        pb = aioadept_pb2.RobotState(
            t_s=float(self.t_s), wall_time_s=float(self.wall_time_s),
            joints_deg=[float(j) for j in self.joints_deg],
            x=p.x, y=p.y, z=p.z, yaw=p.yaw, pitch=p.pitch, roll=p.roll,
            in_motion=bool(self.in_motion), speed_pct=speed, air=bool(self.air),
            outputs_on=self.outputs_on, inputs_on=self.inputs_on, soft_on=self.soft_on,
            changes=[aioadept_pb2.SignalChange(t_s=float(c.t_s), signal=int(c.signal), on=bool(c.on))
                     for c in self.changes],
        )
        if self.hand:
            pb.hand = self.hand
        return pb.SerializeToString()

    @classmethod
    def from_bytes(cls, data: bytes) -> RobotState:
        """Parse ``aioadept.RobotState`` bytes; garbage or missing required fields raise :class:`BusError`."""
        pb = _parse(aioadept_pb2.RobotState(), data, "an aioadept RobotState")
        return cls(
            t_s=pb.t_s, wall_time_s=pb.wall_time_s, joints_deg=tuple(pb.joints_deg),
            pose=Pose(pb.x, pb.y, pb.z, pb.yaw, pb.pitch, pb.roll),
            in_motion=pb.in_motion, speed_pct=pb.speed_pct, air=pb.air,
            outputs_on=tuple(pb.outputs_on), inputs_on=tuple(pb.inputs_on), soft_on=tuple(pb.soft_on),
            hand=pb.hand, changes=tuple(SignalEvent(c.t_s, c.signal, c.on) for c in pb.changes),
        )


# ---------------------------------------------------------------------------------------------------- world state

WORLD_STATE_TOPIC = b"world.state"
"""Topic frame of the simulated world's stream (docs/sim.md, "The world"), published beside ``robot.state``."""


@dataclass(frozen=True, slots=True)
class WorldState:
    """One sample of the simulated world (:mod:`aioadept.world`): at server time ``t_s`` (epoch
    ``wall_time_s``) every part's pose and whether it is held or fell, the world's inputs that are on, and the
    events since the previous sample (:class:`aioadept.world.WorldEvent`; ``seq`` is not sent: 0 here)."""

    t_s: float
    wall_time_s: float
    parts: tuple = ()        # tuple[aioadept.world.PartState, ...]
    events: tuple = ()       # tuple[aioadept.world.WorldEvent, ...]
    sensors_on: tuple[int, ...] = ()

    def to_bytes(self) -> bytes:
        """Serialise as ``aioadept.WorldState``; non-finite times raise :class:`BusEncodeError`."""
        if not (math.isfinite(self.t_s) and math.isfinite(self.wall_time_s)):
            raise BusEncodeError("world state times must be finite", value=(self.t_s, self.wall_time_s))
        pb = aioadept_pb2.WorldState(t_s=float(self.t_s), wall_time_s=float(self.wall_time_s),
                                     sensors_on=[int(n) for n in self.sensors_on])
        for p in self.parts:
            q = p.pose
            pb.parts.add(id=int(p.id), x=q.x, y=q.y, z=q.z, yaw=q.yaw, pitch=q.pitch, roll=q.roll,
                         grasped=bool(p.grasped), dropped=bool(p.dropped))
        for e in self.events:
            pb.events.add(t_s=float(e.t_s), kind=e.kind, part=int(e.part), signal=int(e.signal), on=bool(e.on),
                          text=e.text)
        return pb.SerializeToString()

    @classmethod
    def from_bytes(cls, data: bytes) -> WorldState:
        """Parse ``aioadept.WorldState`` bytes; garbage or missing required fields raise :class:`BusError`."""
        from aioadept.world import PartState, WorldEvent

        pb = _parse(aioadept_pb2.WorldState(), data, "an aioadept WorldState")
        return cls(
            t_s=pb.t_s, wall_time_s=pb.wall_time_s,
            parts=tuple(PartState(p.id, Pose(p.x, p.y, p.z, p.yaw, p.pitch, p.roll), p.grasped, p.dropped)
                        for p in pb.parts),
            events=tuple(WorldEvent(0, e.t_s, e.kind, e.part, e.signal, e.on, e.text) for e in pb.events),
            sensors_on=tuple(pb.sensors_on),
        )

    def part(self, part_id: int):  # -> aioadept.world.PartState
        for p in self.parts:
            if p.id == part_id:
                return p
        raise KeyError(part_id)
