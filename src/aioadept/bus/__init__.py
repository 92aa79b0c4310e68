"""The publish/subscribe bus: ZeroMQ sockets + Protobuf messages, converted to plain values at this edge.

- :mod:`aioadept.bus.messages`: EPypes ``Event``/``Image`` and our ``RobotState`` <-> bytes.
- :mod:`aioadept.bus.pubsub`: owned PUB/SUB sockets with topic frames.
- :mod:`aioadept.bus.communicator`: request -> matching response (the paper's ProtobufCommunicator) and the
  node-side ``Responder``.

See docs/bus.md for the schema, endpoints and the request/response protocol.
"""

from aioadept.bus.communicator import (
    BusObserver,
    Communicator,
    Request,
    Responder,
    Response,
    new_request_id,
    response_type_for,
)
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
from aioadept.bus.pubsub import (
    DEFAULT_REQUEST_ENDPOINT,
    DEFAULT_RESPONSE_ENDPOINT,
    DEFAULT_STATE_ENDPOINT,
    Publisher,
    Subscriber,
    SyncPublisher,
)

__all__ = [
    "BusObserver",
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
    "decode_event",
    "decode_image",
    "encode_event",
    "encode_image",
]
