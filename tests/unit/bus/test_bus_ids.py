"""Request ids and response type naming (no sockets)."""

import re

from aioadept.bus.communicator import Response, new_request_id, response_type_for
from aioadept.errors import VisionError

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
    with pytest.raises(VisionError, match="no object found"):
        bad.raise_for_error()
