from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class RobotState(_message.Message):
    __slots__ = ("t_s", "wall_time_s", "joints_deg", "x", "y", "z", "yaw", "pitch", "roll", "in_motion", "speed_pct", "air", "outputs_on", "inputs_on", "soft_on", "hand", "changes")
    T_S_FIELD_NUMBER: _ClassVar[int]
    WALL_TIME_S_FIELD_NUMBER: _ClassVar[int]
    JOINTS_DEG_FIELD_NUMBER: _ClassVar[int]
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_FIELD_NUMBER: _ClassVar[int]
    YAW_FIELD_NUMBER: _ClassVar[int]
    PITCH_FIELD_NUMBER: _ClassVar[int]
    ROLL_FIELD_NUMBER: _ClassVar[int]
    IN_MOTION_FIELD_NUMBER: _ClassVar[int]
    SPEED_PCT_FIELD_NUMBER: _ClassVar[int]
    AIR_FIELD_NUMBER: _ClassVar[int]
    OUTPUTS_ON_FIELD_NUMBER: _ClassVar[int]
    INPUTS_ON_FIELD_NUMBER: _ClassVar[int]
    SOFT_ON_FIELD_NUMBER: _ClassVar[int]
    HAND_FIELD_NUMBER: _ClassVar[int]
    CHANGES_FIELD_NUMBER: _ClassVar[int]
    t_s: float
    wall_time_s: float
    joints_deg: _containers.RepeatedScalarFieldContainer[float]
    x: float
    y: float
    z: float
    yaw: float
    pitch: float
    roll: float
    in_motion: bool
    speed_pct: int
    air: bool
    outputs_on: _containers.RepeatedScalarFieldContainer[int]
    inputs_on: _containers.RepeatedScalarFieldContainer[int]
    soft_on: _containers.RepeatedScalarFieldContainer[int]
    hand: str
    changes: _containers.RepeatedCompositeFieldContainer[SignalChange]
    def __init__(self, t_s: _Optional[float] = ..., wall_time_s: _Optional[float] = ..., joints_deg: _Optional[_Iterable[float]] = ..., x: _Optional[float] = ..., y: _Optional[float] = ..., z: _Optional[float] = ..., yaw: _Optional[float] = ..., pitch: _Optional[float] = ..., roll: _Optional[float] = ..., in_motion: _Optional[bool] = ..., speed_pct: _Optional[int] = ..., air: _Optional[bool] = ..., outputs_on: _Optional[_Iterable[int]] = ..., inputs_on: _Optional[_Iterable[int]] = ..., soft_on: _Optional[_Iterable[int]] = ..., hand: _Optional[str] = ..., changes: _Optional[_Iterable[_Union[SignalChange, _Mapping]]] = ...) -> None: ...

class SignalChange(_message.Message):
    __slots__ = ("t_s", "signal", "on")
    T_S_FIELD_NUMBER: _ClassVar[int]
    SIGNAL_FIELD_NUMBER: _ClassVar[int]
    ON_FIELD_NUMBER: _ClassVar[int]
    t_s: float
    signal: int
    on: bool
    def __init__(self, t_s: _Optional[float] = ..., signal: _Optional[int] = ..., on: _Optional[bool] = ...) -> None: ...

class WorldState(_message.Message):
    __slots__ = ("t_s", "wall_time_s", "parts", "events", "sensors_on")
    T_S_FIELD_NUMBER: _ClassVar[int]
    WALL_TIME_S_FIELD_NUMBER: _ClassVar[int]
    PARTS_FIELD_NUMBER: _ClassVar[int]
    EVENTS_FIELD_NUMBER: _ClassVar[int]
    SENSORS_ON_FIELD_NUMBER: _ClassVar[int]
    t_s: float
    wall_time_s: float
    parts: _containers.RepeatedCompositeFieldContainer[PartPose]
    events: _containers.RepeatedCompositeFieldContainer[WorldEvent]
    sensors_on: _containers.RepeatedScalarFieldContainer[int]
    def __init__(self, t_s: _Optional[float] = ..., wall_time_s: _Optional[float] = ..., parts: _Optional[_Iterable[_Union[PartPose, _Mapping]]] = ..., events: _Optional[_Iterable[_Union[WorldEvent, _Mapping]]] = ..., sensors_on: _Optional[_Iterable[int]] = ...) -> None: ...

class PartPose(_message.Message):
    __slots__ = ("id", "x", "y", "z", "yaw", "pitch", "roll", "grasped", "dropped")
    ID_FIELD_NUMBER: _ClassVar[int]
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_FIELD_NUMBER: _ClassVar[int]
    YAW_FIELD_NUMBER: _ClassVar[int]
    PITCH_FIELD_NUMBER: _ClassVar[int]
    ROLL_FIELD_NUMBER: _ClassVar[int]
    GRASPED_FIELD_NUMBER: _ClassVar[int]
    DROPPED_FIELD_NUMBER: _ClassVar[int]
    id: int
    x: float
    y: float
    z: float
    yaw: float
    pitch: float
    roll: float
    grasped: bool
    dropped: bool
    def __init__(self, id: _Optional[int] = ..., x: _Optional[float] = ..., y: _Optional[float] = ..., z: _Optional[float] = ..., yaw: _Optional[float] = ..., pitch: _Optional[float] = ..., roll: _Optional[float] = ..., grasped: _Optional[bool] = ..., dropped: _Optional[bool] = ...) -> None: ...

class WorldEvent(_message.Message):
    __slots__ = ("t_s", "kind", "part", "signal", "on", "text")
    T_S_FIELD_NUMBER: _ClassVar[int]
    KIND_FIELD_NUMBER: _ClassVar[int]
    PART_FIELD_NUMBER: _ClassVar[int]
    SIGNAL_FIELD_NUMBER: _ClassVar[int]
    ON_FIELD_NUMBER: _ClassVar[int]
    TEXT_FIELD_NUMBER: _ClassVar[int]
    t_s: float
    kind: str
    part: int
    signal: int
    on: bool
    text: str
    def __init__(self, t_s: _Optional[float] = ..., kind: _Optional[str] = ..., part: _Optional[int] = ..., signal: _Optional[int] = ..., on: _Optional[bool] = ..., text: _Optional[str] = ...) -> None: ...
