"""Request ids and response type naming (no sockets)."""

import re

from aioadept.bus.pairing import Response, new_request_id
from aioadept.bus.pairing import response_type_for
from aioadept.errors import RemoteError
from aioadept.errors import BusError, VisionError
from aioadept.vision import raise_for_error

import pytest


def test_request_ids_look_like_robot_message_ids_and_differ():
    ids = {new_request_id() for _ in range(2000)}
    assert len(ids) == 2000
    assert all(re.fullmatch(r"[0-9a-f]{8}", i) for i in ids)


@pytest.mark.parametrize("req, resp", [("VisionRequest", "VisionResponse"), ("Grab", "GrabResponse"),
                                       ("Request", "Response")])
def test_response_type_for(req, resp):
    assert response_type_for(req) == resp


def test_response_error_helpers():
    ok = Response("0badcafe", "VisionResponse", {"sharpness": 1.0}, 1.0, 1.25)
    assert ok.error is None and ok.raise_for_error() is ok and ok.latency_s == 0.25
    bad = Response("0badcafe", "VisionResponse", {"error": "no object found"}, 1.0, 1.5)
    with pytest.raises(RemoteError, match="no object found") as info:
        bad.raise_for_error()
    # The bus raises its own error; it knows nothing of vision.
    assert isinstance(info.value, BusError) and not isinstance(info.value, VisionError)
    assert info.value.attributes == {"error": "no object found"} and info.value.request_id == "0badcafe"
    assert info.value.error == "no object found"


def test_vision_maps_an_error_answer_to_vision_error():
    ok = Response("0badcafe", "VisionResponse", {"sharpness": 1.0}, 1.0, 1.25)
    assert raise_for_error(ok) is ok
    bad = Response("0badcafe", "VisionResponse", {"error": "no object found"}, 1.0, 1.5)
    with pytest.raises(VisionError, match="no object found") as info:
        raise_for_error(bad)
    assert info.value.attributes == {"error": "no object found"}
    assert isinstance(info.value.__cause__, RemoteError)
