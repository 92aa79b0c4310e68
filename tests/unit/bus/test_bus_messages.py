"""Schema round trips and wire compatibility with EPypes' own message definitions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import epypes_reference as ref
from aioadept.bus import aioadept_pb2, epypes_pb2
from aioadept.bus.messages import (
    SignalEvent,
    INT32_MAX,
    INT32_MIN,
    EventMessage,
    ImageMessage,
    RobotState,
    decode_event,
    decode_image,
    encode_event,
    encode_image,
)
from aioadept.errors import BusEncodeError, BusError
from aioadept.geometry import Pose

keys = st.text(min_size=0, max_size=12)
values = st.one_of(
    st.text(max_size=20),
    st.floats(allow_nan=False),
    st.integers(min_value=INT32_MIN, max_value=INT32_MAX),
)
attr_dicts = st.dictionaries(keys, values, max_size=8)


@given(etype=st.text(max_size=20), eid=st.one_of(st.none(), st.text(max_size=10)), attrs=attr_dicts)
def test_event_round_trip_keeps_type_id_and_typed_attributes(etype, eid, attrs):
    t, i, a = decode_event(encode_event(etype, eid, attrs))
    assert (t, i, a) == (etype, eid, attrs)
    assert [type(v) for v in a.values()] == [type(v) for v in attrs.values()]


def test_event_message_dataclass_round_trip():
    ev = EventMessage("VisionResponse", "eae86869", {"sharpness": 12.5, "error": "", "n": -3})
    assert EventMessage.from_bytes(ev.to_bytes()) == ev


def test_nan_and_inf_survive():
    _, _, a = decode_event(encode_event("x", None, {"nan": math.nan, "inf": -math.inf}))
    assert math.isnan(a["nan"]) and a["inf"] == -math.inf


def test_numpy_scalars_are_typed_like_python_numbers():
    _, _, a = decode_event(encode_event("x", "1", {"f": np.float32(0.5), "i": np.int64(7), "d": np.float64(1.25)}))
    assert a == {"f": 0.5, "i": 7, "d": 1.25}
    assert type(a["i"]) is int and type(a["f"]) is float


@pytest.mark.parametrize("bad", [True, np.bool_(False), None, b"bytes", [1.0], 2**31, INT32_MIN - 1, 1 + 2j])
def test_values_the_schema_cannot_carry_raise_before_sending(bad):
    with pytest.raises(BusEncodeError) as info:
        encode_event("x", "1", {"k": bad})
    assert info.value.key == "k"
    assert isinstance(info.value, ValueError) and isinstance(info.value, BusError)


def test_int32_bounds_are_accepted():
    _, _, a = decode_event(encode_event("x", None, {"lo": INT32_MIN, "hi": INT32_MAX}))
    assert a == {"lo": INT32_MIN, "hi": INT32_MAX}


@pytest.mark.parametrize("garbage", [b"\x0a\x05abc", b"\xff\xff\xff", b"", b"\x12\x02ab"])
def test_garbage_and_missing_required_fields_raise_bus_error(garbage):
    with pytest.raises(BusError):
        decode_event(garbage)


def test_absent_id_is_none_but_empty_id_is_kept():
    assert decode_event(encode_event("x"))[1] is None
    assert decode_event(encode_event("x", ""))[1] == ""


# ---------------------------------------------------------------------------------------------- EPypes compatibility

def test_our_event_bytes_decode_with_epypes_definition():
    data = encode_event("VisionRequest", "eae86869", {"t_request": 1700000000.25, "camera": "left", "n": 5})
    pb = ref.Event()
    pb.ParseFromString(data)
    assert pb.IsInitialized()
    assert (pb.type, pb.id) == ("VisionRequest", "eae86869")
    got = {e.key: (e.type, e.str_val if e.type == 1 else e.double_val if e.type == 2 else e.int_val)
           for e in pb.attributes.entries}
    assert got == {"t_request": (2, 1700000000.25), "camera": (1, "left"), "n": (3, 5)}


def test_epypes_event_bytes_decode_with_ours():
    pb = ref.Event(type="VisionResponse", id="0badcafe")
    for k, v in (("sharpness", 41.5), ("error", "no object found"), ("count", -2)):
        ref.add_attribute(pb, k, v)
    assert decode_event(pb.SerializeToString()) == (
        "VisionResponse", "0badcafe", {"sharpness": 41.5, "error": "no object found", "count": -2})


def test_bytes_are_identical_to_epypes_serialisation():
    # Same field order and numbers => byte-identical output, the strongest form of wire compatibility.
    pb = ref.Event(type="VisionRequest", id="12345678")
    ref.add_attribute(pb, "t_request", 3.5)
    ref.add_attribute(pb, "camera", "c0")
    assert encode_event("VisionRequest", "12345678", {"t_request": 3.5, "camera": "c0"}) == pb.SerializeToString()


def test_image_both_directions_with_epypes_definition():
    ours = encode_image(b"\x00\x01\xff" * 10, id="i1", format="mono8:10x3", attributes={"t": 2.0})
    pb = ref.Image()
    pb.ParseFromString(ours)
    assert (pb.bytes, pb.id, pb.format) == (b"\x00\x01\xff" * 10, "i1", "mono8:10x3")
    theirs = ref.Image(bytes=b"png...", format="png")
    ref.add_attribute(theirs, "frame_t", 9.0)
    assert decode_image(theirs.SerializeToString()) == ImageMessage(b"png...", None, "png", {"frame_t": 9.0})


def test_generated_descriptor_matches_the_epypes_schema_field_by_field():
    for name in ("Attribute", "AttributeList", "Event", "Image"):
        ours = epypes_pb2.DESCRIPTOR.message_types_by_name[name]
        theirs = ref._POOL.FindMessageTypeByName(name)
        assert [(f.name, f.number, f.type, f.is_required, f.is_repeated) for f in ours.fields] == \
            [(f.name, f.number, f.type, f.is_required, f.is_repeated) for f in theirs.fields]
    enum = epypes_pb2.Attribute.Type
    assert (enum.Value("STRING"), enum.Value("DOUBLE"), enum.Value("INT")) == (1, 2, 3)


def test_image_message_round_trip_and_bad_data():
    im = ImageMessage(b"abc", "x", None, {"w": 3})
    assert ImageMessage.from_bytes(im.to_bytes()) == im
    with pytest.raises(BusEncodeError):
        encode_image("not bytes")  # type: ignore[arg-type]
    with pytest.raises(BusError):
        decode_image(b"")


# ---------------------------------------------------------------------------------------------- robot state

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@given(t=finite, wall=finite, joints=st.lists(finite, min_size=6, max_size=6), pose=st.lists(finite, min_size=6,
       max_size=6), moving=st.booleans(), speed=st.integers(0, 100), air=st.booleans())
def test_robot_state_round_trip(t, wall, joints, pose, moving, speed, air):
    s = RobotState(t, wall, tuple(joints), Pose(*pose), in_motion=moving, speed_pct=speed, air=air)
    assert RobotState.from_bytes(s.to_bytes()) == s


def test_robot_state_field_numbers_are_stable():
    pb = aioadept_pb2.RobotState()
    pb.ParseFromString(RobotState(1.5, 2.5, (0, -90, 180, 0, 90, 0), Pose(1, 2, 3, 4, 5, 6), True, 40, True)
                       .to_bytes())
    assert (pb.t_s, pb.wall_time_s, list(pb.joints_deg), pb.roll, pb.speed_pct, pb.in_motion, pb.air) == (
        1.5, 2.5, [0, -90, 180, 0, 90, 0], 6.0, 40, True, True)
    assert [f.number for f in pb.DESCRIPTOR.fields] == list(range(1, 18))


def test_robot_state_io_round_trip_and_field_numbers():
    s = RobotState(1.0, 2.0, (0,) * 6, Pose(), outputs_on=(1, 8), inputs_on=(1001,), soft_on=(2001, 2512),
                   hand="closing", changes=(SignalEvent(0.5, 8, True), SignalEvent(0.75, 1001, False)))
    assert RobotState.from_bytes(s.to_bytes()) == s
    pb = aioadept_pb2.RobotState()
    pb.ParseFromString(s.to_bytes())
    assert (list(pb.outputs_on), list(pb.inputs_on), list(pb.soft_on), pb.hand) == ([1, 8], [1001], [2001, 2512],
                                                                                   "closing")
    assert [(c.t_s, c.signal, c.on) for c in pb.changes] == [(0.5, 8, True), (0.75, 1001, False)]
    assert [f.number for f in aioadept_pb2.SignalChange.DESCRIPTOR.fields] == [1, 2, 3]
    # a sample without I/O (an older publisher) reads as empty, not as an error
    old = RobotState(1.0, 2.0, (0,) * 6, Pose())
    assert RobotState.from_bytes(old.to_bytes()).hand == "" and RobotState.from_bytes(old.to_bytes()).changes == ()


def test_robot_state_errors():
    with pytest.raises(BusError):
        RobotState.from_bytes(b"")
    with pytest.raises(BusError):
        RobotState.from_bytes(b"\xff")
    with pytest.raises(BusEncodeError):
        RobotState(math.nan, 0.0, (0,) * 6, Pose()).to_bytes()


@pytest.mark.parametrize("shape", [(4, 6), (4, 6, 3)])
@pytest.mark.parametrize("encoding", ["raw", "png"])
def test_image_arrays_round_trip_through_the_wire(shape, encoding):
    rng = np.random.default_rng(0)
    arr = rng.integers(0, 256, size=shape, dtype=np.uint8)
    msg = ImageMessage.from_array(arr, encoding=encoding, id="f1", attributes={"frame_t": 1.5})
    back = ImageMessage.from_bytes(msg.to_bytes())
    assert back == msg and back.attributes == {"frame_t": 1.5}
    assert np.array_equal(back.to_array(), arr)  # png is lossless
    if encoding == "raw":
        assert back.format == ("mono8:6x4" if len(shape) == 2 else "bgr8:6x4")


def test_image_array_errors():
    with pytest.raises(BusEncodeError):
        ImageMessage.from_array(np.zeros((2, 2), dtype=np.float32))
    with pytest.raises(BusEncodeError):
        ImageMessage.from_array(np.zeros((2, 2), dtype=np.uint8), encoding="gif")
    with pytest.raises(BusError):
        ImageMessage(b"\x00" * 5, format="mono8:2x2").to_array()
    with pytest.raises(BusError):
        ImageMessage(b"not an image", format="png").to_array()


# ---------------------------------------------------------------------------------------------------- world state

def test_world_state_round_trips_parts_events_and_sensors():
    from aioadept.bus.messages import WorldState
    from aioadept.world import PartState, WorldEvent

    st = WorldState(12.5, 1.7e9, (PartState(1, Pose(1.0, 2.0, 3.0, 0.0, 0.0, 30.0), grasped=True),
                                  PartState(2, Pose(-5.0, 0.5, 0.0), dropped=True)),
                    (WorldEvent(0, 12.4, "dropped", part=2, text="part 2 dropped"),
                     WorldEvent(0, 12.45, "sensor", signal=1002, on=True)), (1002,))
    back = WorldState.from_bytes(st.to_bytes())
    assert back == st
    assert back.part(1).grasped and back.part(2).dropped and back.events[0].error


def test_world_state_garbage_and_bad_times_are_bus_errors():
    from aioadept.bus.messages import WorldState

    with pytest.raises(BusError):
        WorldState.from_bytes(b"\x08\x01")  # a varint field 1: not the double t_s, and wall_time_s missing
    with pytest.raises(BusEncodeError):
        WorldState(float("nan"), 0.0).to_bytes()
