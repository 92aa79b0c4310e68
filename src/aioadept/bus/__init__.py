"""The publish/subscribe bus: ZeroMQ sockets + Protobuf messages, converted to plain values at this edge.

By role, over one socket layer:

- :mod:`aioadept.bus.sockets`: the socket layer every role uses (options, CURVE, bind/connect, reading, close).
- :mod:`aioadept.bus.pubsub`: publisher and subscriber roles (asyncio and plain-thread), topic frames.
- :mod:`aioadept.bus.pairing`: request/response vocabulary shared by both sides, and the one pending registry.
- :mod:`aioadept.bus.communicator`: the requester side (the paper's ProtobufCommunicator).
- :mod:`aioadept.bus.responder`: the responder side (a node answering requests).
- :mod:`aioadept.bus.messages`: the edge to Protobuf: EPypes ``Event``/``Image`` and our ``RobotState`` <-> bytes.
- :mod:`aioadept.bus.endpoints`, :mod:`aioadept.bus.security`: CZMQ endpoints, CURVE.
- What the bus raises (``BusError`` and below, ``RemoteError`` for an ``error`` answer) is in
  :mod:`aioadept.errors`, re-exported here. The bus knows none of its users: vision maps its errors itself (:func:`aioadept.vision.responses.raise_for_error`).

See docs/bus.md for the schema, endpoints and the request/response protocol.
"""

from aioadept.bus.communicator import Communicator
from aioadept.errors import BusEncodeError, BusError, RemoteError, RequestTimeout
from aioadept.bus.messages import (
    ROBOT_STATE_TOPIC,
    EventMessage,
    ImageMessage,
    RobotState,
    decode_event,
    decode_image,
    encode_event,
    encode_image,
)
from aioadept.bus.pairing import BusObserver, Request, Response, new_request_id, response_type_for
from aioadept.bus.pubsub import (
    DEFAULT_REQUEST_ENDPOINT,
    DEFAULT_RESPONSE_ENDPOINT,
    DEFAULT_STATE_ENDPOINT,
    Publisher,
    Subscriber,
    SyncPublisher,
    SyncSubscriber,
)
from aioadept.bus.responder import Responder

__all__ = [
    "BusEncodeError",
    "BusError",
    "BusObserver",
    "RemoteError",
    "RequestTimeout",
    "Communicator",
    "Request",
    "Responder",
    "Response",
    "new_request_id",
    "response_type_for",
    "DEFAULT_REQUEST_ENDPOINT",
    "DEFAULT_RESPONSE_ENDPOINT",
    "DEFAULT_STATE_ENDPOINT",
    "ROBOT_STATE_TOPIC",
    "EventMessage",
    "ImageMessage",
    "Publisher",
    "RobotState",
    "Subscriber",
    "SyncPublisher",
    "SyncSubscriber",
    "decode_event",
    "decode_image",
    "encode_event",
    "encode_image",
]
