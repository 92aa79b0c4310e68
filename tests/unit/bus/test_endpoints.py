"""CZMQ-style endpoints: '@' binds, '>' connects, bare takes the role's default (publishers bind, subscribers
connect); one parser for every endpoint option."""

from __future__ import annotations

import pytest
import zmq

from aioadept.bus.endpoints import opposite, parse_endpoint, peer, peer_actual, resolve
from aioadept.bus.pubsub import Publisher, Subscriber
from aioadept.errors import BusError


@pytest.mark.parametrize("text, default, expected", [
    ("@tcp://127.0.0.1:5555", False, ("tcp://127.0.0.1:5555", True)),
    (">tcp://127.0.0.1:5555", True, ("tcp://127.0.0.1:5555", False)),
    ("tcp://127.0.0.1:5555", True, ("tcp://127.0.0.1:5555", True)),
    ("tcp://127.0.0.1:5555", False, ("tcp://127.0.0.1:5555", False)),
    ("tcp://127.0.0.1:0", False, ("tcp://127.0.0.1:0", True)),   # port 0 can only be bound
    ("tcp://*:5555", False, ("tcp://*:5555", True)),
    (" ipc:///tmp/x ", False, ("ipc:///tmp/x", False)),
])
def test_resolve(text, default, expected):
    assert resolve(text, default) == expected


@pytest.mark.parametrize("text, why", [
    ("tcp:/127.0.0.1:1", "expected [@|>]transport://address"),
    ("127.0.0.1:5555", "expected [@|>]transport://address"),
    ("@", "expected"),
    ("foo://x", "unknown transport"),
    (">tcp://127.0.0.1:0", "cannot connect to a wildcard"),
    (">tcp://*:5", "cannot connect to a wildcard"),
    ("@tcp://a:1,>tcp://b:2", "one address"),
])
def test_bad_endpoints_say_why(text, why):
    with pytest.raises(BusError, match=why.replace("[", r"\[").replace("|", r"\|")):
        parse_endpoint(text)


def test_peer_and_opposite():
    assert peer("tcp://127.0.0.1:5555", False) == "@tcp://127.0.0.1:5555"  # I connect: you bind
    assert peer("tcp://127.0.0.1:5555", True) == ">tcp://127.0.0.1:5555"
    assert peer("@tcp://127.0.0.1:5555", False) == ">tcp://127.0.0.1:5555"
    assert peer_actual("tcp://127.0.0.1:0", False, "tcp://127.0.0.1:4242") == ">tcp://127.0.0.1:4242"
    assert opposite("@tcp://h:1") == ">tcp://h:1" and opposite(">tcp://h:1") == "@tcp://h:1"
    assert opposite("tcp://h:1") == "tcp://h:1"
    assert str(parse_endpoint("@tcp://h:1")) == "@tcp://h:1"


def test_sockets_follow_the_prefix_and_the_role_default():
    ctx = zmq.Context()
    try:
        pub = Publisher("tcp://127.0.0.1:0", context=ctx)  # bare PUB binds
        sub = Subscriber(pub.actual_endpoint, context=ctx)      # bare SUB connects
        sub_bound = Subscriber("@tcp://127.0.0.1:0", context=ctx)
        pub2 = Publisher(">" + sub_bound.actual_endpoint, context=ctx)
        assert pub.bound and not sub.bound and sub_bound.bound and not pub2.bound
        for s in (pub, sub, sub_bound, pub2):
            s.close()
        with pytest.raises(BusError, match="Protocol not supported|expected"):
            Publisher("tcp:/nope", context=ctx)
    finally:
        ctx.term()
