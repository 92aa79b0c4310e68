"""The DAP layer's checks without a process: launch arguments, --listen, framing, bad requests."""

from __future__ import annotations

import asyncio
import json

import pytest

from aioadept.vplus import dap
from aioadept.vplus.daplaunch import LaunchError, launch_args


@pytest.mark.parametrize(("args", "says"), [
    ({"program": "rs.main"}, "modules must be a list"),
    ({"modules": ["a.V2"]}, "program must name"),
    ({"modules": ["a.V2"], "program": "p", "task": 99}, "task 99"),
    ({"modules": ["a.V2"], "program": "p", "portMap": {"x": 1}}, "portMap: ports must be numbers"),
    ({"modules": ["a.V2"], "program": "p", "timeScale": 0}, "timeScale 0"),
    ({"modules": ["a.V2"], "program": "p", "progam": "q"}, "unknown argument 'progam'"),
])
def test_a_bad_launch_argument_is_named(args, says):
    with pytest.raises(LaunchError, match=says):
        launch_args(args)


def test_listen_is_loopback_only():
    assert dap.parse_listen("127.0.0.1:4711") == ("127.0.0.1", 4711)
    for bad, says in (("0.0.0.0:4711", "on loopback only"), ("127.0.0.1:x", "not a port"), ("4711", "expected")):
        with pytest.raises(ValueError, match=says):
            dap.parse_listen(bad)


async def test_framing_and_bad_requests_get_error_responses_and_the_session_goes_on():
    sent: list[dict] = []

    def send(data: bytes) -> None:
        head, _, body = data.partition(b"\r\n\r\n")
        assert head == b"Content-Length: %d" % len(body)
        sent.append(json.loads(body))

    reader = asyncio.StreamReader()
    for msg in ({"seq": 1, "type": "request", "command": "stackTrace", "arguments": {}},
                {"seq": 2, "type": "request", "command": "launch", "arguments": {"modules": "x"}},
                {"seq": 3, "type": "request", "command": "frobnicate"},
                {"seq": 4, "type": "request", "command": "initialize", "arguments": {}}):
        reader.feed_data(dap.frame_message(msg))
    reader.feed_data(b"Content-Length: 5\r\n\r\n{oops")
    reader.feed_eof()
    await dap.run(dap.Adapter(send), reader)
    responses = {m["request_seq"]: m for m in sent if m["type"] == "response"}
    assert not responses[1]["success"] and "no program is launched" in responses[1]["message"]
    assert not responses[2]["success"] and "modules must be a list" in responses[2]["message"]
    assert not responses[3]["success"] and "not supported" in responses[3]["message"]
    assert responses[4]["success"] and responses[4]["body"]["supportsConditionalBreakpoints"]
    outputs = [m["body"]["output"] for m in sent if m.get("event") == "output"]
    assert any("not a Debug Adapter Protocol message" in o for o in outputs)
    assert sent[-1]["event"] == "terminated"
