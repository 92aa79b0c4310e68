"""The robot bridge's payloads (aioadept.bridge.wire): bytes in, values out, no Zenoh."""

from __future__ import annotations

import pytest

from aioadept.bridge.wire import (
    ERR_KINDS,
    MAX_BATCH,
    BridgeFailure,
    app_key,
    apps_key,
    bridge_key,
    cmd_key,
    encode_failure,
    encode_request,
    parse_failure,
    parse_request,
    state_key,
)
from aioadept.errors import MalformedRequest
from aioadept.commands import Break, MoveJoints, SetSpeed
from aioadept.protocol import SkillCall


def test_keys_name_cell_robot_and_purpose():
    assert bridge_key("demo", "robot") == "aioadept/demo/robot"
    assert cmd_key("demo", "robot") == "aioadept/demo/robot/cmd"
    assert state_key("demo", "r-1") == "aioadept/demo/r-1/state"
    assert apps_key("demo", "robot") == "aioadept/demo/robot/apps/*"
    assert app_key("demo", "robot", "focus") == "aioadept/demo/robot/apps/focus"


@pytest.mark.parametrize("bad", ["", "a/b", "*", "x" * 65, "sp ace", "é"])
def test_a_name_that_is_not_one_key_chunk_is_refused_naming_it(bad):
    with pytest.raises(ValueError, match="application"):
        app_key("demo", "robot", bad)


def test_a_request_round_trips_with_the_application_s_ids():
    calls = (*SetSpeed(20).calls(), *MoveJoints([0, -90, 180, 0, 90, 0]).calls(), *Break().calls())
    ids = tuple(f"{n:08x}" for n in range(1, len(calls) + 1))
    payload = encode_request(ids, calls)
    assert payload.startswith(b"00000001:set_speed:20\r\n00000002:move_joints:0.000,-90.000,")
    req = parse_request(payload, b"focus")
    assert req.app == "focus" and req.ids == ids and req.calls == calls and not req.is_stop
    assert parse_request(b"0000abcd:stop\r\n", b"a").is_stop
    assert parse_request(b"0000abcd:here\n0000abce:here", b"a").ids == ("0000abcd", "0000abce")  # LF alone


@pytest.mark.parametrize(("payload", "app", "said"), [
    (b"0000abcd:here\r\n", None, "no application name"),
    (b"0000abcd:here\r\n", b"", "no application name"),
    (b"0000abcd:here\r\n", b"a/b", "application name"),
    (b"0000abcd:here\r\n", b"\xff", "application name"),
    (b"", b"a", "empty query"),
    (b"\r\n\r\n", b"a", "empty query"),
    (b"garbage", b"a", "line 1"),
    (b"0000abcd:here\r\nzz:here\r\n", b"a", "line 2"),
    (b"0000abcd:move_to:1,nan,3,4,5,6\r\n", b"a", "line 1"),
    (b"0000abcd:here\r\n0000abcd:here\r\n", b"a", "used twice"),
    (b"0000abcd:here\r\n0000abce:stop\r\n", b"a", "stop travels alone"),
    (b"".join(b"%08x:here\r\n" % (n + 1) for n in range(MAX_BATCH + 1)), b"a", "over 64"),
])
def test_a_malformed_request_is_refused_with_what_is_wrong(payload, app, said):
    with pytest.raises(MalformedRequest, match=said):
        parse_request(payload, app)


def test_a_batch_of_the_maximum_size_is_taken():
    payload = b"".join(b"%08x:here\r\n" % (n + 1) for n in range(MAX_BATCH))
    assert len(parse_request(payload, b"a").calls) == MAX_BATCH


@pytest.mark.parametrize("f", [
    BridgeFailure("lost", "controller link lost: reset", ("00000001",), ("00000002", "00000003")),
    BridgeFailure("aborted", "stop from application 'a' before it was sent"),
    BridgeFailure("malformed", "line 1 b'x': 3 colons: here"),
    *(BridgeFailure(k, "t") for k in ERR_KINDS),
])
def test_a_failure_round_trips(f):
    assert parse_failure(encode_failure(f)) == f


def test_a_failure_text_is_one_line_and_an_unknown_kind_is_refused():
    assert encode_failure(BridgeFailure("closed", "a\nb\r\nc")) == b"closed:::a b c"
    with pytest.raises(ValueError, match="kind"):
        encode_failure(BridgeFailure("nope", "t"))
    assert parse_failure(b"what is this") == BridgeFailure("malformed", "what is this")


def test_skill_calls_are_validated_as_on_tcp():
    with pytest.raises(MalformedRequest):
        parse_request(b"0000abcd:" + b"x" * 200 + b"\r\n", b"a")
    assert parse_request(b"0000abcd:move_rel_tool:0,0,-2.5,0,0,0\r\n", b"a").calls == (
        SkillCall("move_rel_tool", (0, 0, -2.5, 0, 0, 0)),)
