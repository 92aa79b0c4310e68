"""The one exception tree of aioadept.

Errors from sockets, ZeroMQ and Protobuf are translated into these where they enter the library, so user code
catches our types only::

    AdeptError
    ├─ ProtocolError
    │   ├─ LocalProtocolError      we were asked to send something the protocol cannot carry
    │   └─ RemoteProtocolError     the peer sent bytes that do not parse (carries a V+-style code)
    ├─ CommandError                the server answered a command with an ``error`` ack
    ├─ CommandAborted              the server flushed a command with an ``aborted`` ack (after a stop)
    │   └─ AbortedBeforeSend       a stop() came while the command waited to be written: it was never sent
    ├─ ConnectError                could not connect to a robot server (refused, unreachable, rejected)
    │   └─ NotARobotServer         the peer did not answer the connect-time ``hello`` like a RobotServer
    ├─ ConnectionLost              the connection dropped; says which messages are known done and which are unknown
    ├─ AckTimeout (TimeoutError)   no ack in time
    ├─ ClientStateError            not connected / closed / reentered
    │   └─ TooManyPending          a write would leave more commands pending than the server admits (nothing sent)
    ├─ BusError                    ZeroMQ/Protobuf failures at the bus edge
    │   ├─ RequestTimeout (TimeoutError)   no response to a bus request in time
    │   └─ BusEncodeError (ValueError)     a value the bus schema cannot carry
    ├─ VisionError                 a vision node answered with an error result (e.g. no object found)
    └─ RobotError                  the simulated controller refused a motion (reach, joint limit); carries the code

The applications add their own subclasses of ``AdeptError`` beside their code: ``apps.focus.FocusError`` (and
``FocusStopped``), ``apps.focus.StopFailed`` (a stop the app sent was not acked ``done``: the robot may still be
moving), ``capture.RunSaveError`` (an ``OSError``, not an ``AdeptError``: run folder files not written) and ``apps.processes.NodeError`` (a node process failed to start or died).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

# The root and the protocol errors live in the sans-IO core (it imports nothing from here); the tree is one.
from aioadept.protocol.errors import AdeptError, LocalProtocolError, ProtocolError, RemoteProtocolError

if TYPE_CHECKING:  # pragma: no cover
    from aioadept.protocol import Ack

__all__ = [
    "AbortedBeforeSend", "AckTimeout", "AdeptError", "BusEncodeError", "BusError", "ClientStateError",
    "CommandAborted", "CommandError", "ConnectError", "ConnectionLost", "GraphError", "LocalProtocolError",
    "NotARobotServer", "ObjectNotFound", "ProtocolError", "RemoteProtocolError", "RequestTimeout", "RobotError",
    "TooManyPending", "VisionError",
]


class CommandError(AdeptError):
    """The server answered a command with an ``error`` ack; the robot did not execute it."""

    def __init__(self, ack: Ack, skill: str | None = None) -> None:
        code = ack.error_code
        msg = ack.error_message or ""
        where = f" {skill}" if skill else ""
        super().__init__(f"command {ack.id}{where} failed: {msg} (code {code})")
        self.ack = ack
        self.code = code
        self.message = msg
        self.skill = skill


class CommandAborted(AdeptError):
    """The server flushed a command with an ``aborted`` ack, normally because a stop was requested."""

    def __init__(self, ack: Ack | None, skill: str | None = None, *, message: str | None = None) -> None:
        if message is None:
            message = f"command {ack.id if ack is not None else ''} {skill or ''} was aborted"
        super().__init__(" ".join(message.split()))
        self.ack = ack
        self.skill = skill


class AbortedBeforeSend(CommandAborted):
    """A ``stop()`` was requested while this command was still waiting to be written (for example while the client
    reconnected): the client never sent it, as the server would have aborted it had it arrived before the stop.
    ``ack`` is None; ``skill`` names the first skill not sent."""

    def __init__(self, skill: str | None = None) -> None:
        super().__init__(None, skill, message=f"{skill or 'command'} not sent: stop() was requested before it was "
                                              "written")


class ConnectError(AdeptError):
    """A connection to the robot server could not be established."""


class NotARobotServer(ConnectError):
    """The peer accepted the TCP connection but did not answer ``hello`` like a RobotServer (wrong port?)."""


class ConnectionLost(AdeptError):
    """The connection to the server dropped while messages were pending.

    ``acked`` lists the message IDs that were acknowledged (known done), ``unresolved`` the ones sent or queued
    whose fate is unknown: they may or may not have run on the robot. Nothing is re-sent automatically.
    """

    def __init__(self, message: str, *, acked: tuple[str, ...] = (), unresolved: tuple[str, ...] = ()) -> None:
        detail = f"{message}; acked={list(acked)} unresolved={list(unresolved)}"
        super().__init__(detail)
        self.acked = tuple(acked)
        self.unresolved = tuple(unresolved)


class AckTimeout(AdeptError, TimeoutError):
    """No acknowledgement arrived within the timeout. ``pending`` lists the IDs still waiting."""

    def __init__(self, message: str, *, pending: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.pending = tuple(pending)


class ClientStateError(AdeptError):
    """The client is used in a state that does not allow it (not connected, closed, reentered)."""


class TooManyPending(ClientStateError):
    """Writing these messages would leave more than ``limit`` commands pending on the connection, more than the
    server admits (it would refuse the excess with ``-530``, perhaps in the middle of a sequence of motions while
    the rest runs). Nothing was written. Wait for acks, or send fewer at once."""

    def __init__(self, message: str, *, pending: int, wanted: int, limit: int) -> None:
        super().__init__(message)
        self.pending = pending
        self.wanted = wanted
        self.limit = limit


class BusError(AdeptError):
    """A failure at the publish/subscribe edge (ZeroMQ or Protobuf)."""


class RequestTimeout(BusError, TimeoutError):
    """A bus request got no matching response in time."""

    def __init__(self, message: str, *, request_id: str | None = None, **extra: Any) -> None:
        super().__init__(message)
        self.request_id = request_id
        self.extra = extra


class VisionError(AdeptError):
    """A vision node answered a request with an error result (for example: no calibration object found)."""

    def __init__(self, message: str, *, attributes: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.attributes = dict(attributes or {})


class RobotError(AdeptError):
    """The (simulated) controller refused a motion: target out of reach, joint limit, bad value."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(f"{message} (code {code})")
        self.code = code
        self.message = message


class BusEncodeError(BusError, ValueError):
    """A value the bus schema cannot carry: an attribute of another type than str/float/int (bool included, as in
    EPypes), an int outside int32, a missing required field. ``key`` names the offending attribute when there is one.
    """

    def __init__(self, message: str, *, key: str | None = None, value: Any = None) -> None:
        super().__init__(message)
        self.key = key
        self.value = value


class GraphError(AdeptError, ValueError):
    """A computational graph is inconsistent (cycle, token produced twice, missing input) or misused at run time.

    Part of the vision side (:mod:`aioadept.vision.graph`); ``tokens`` names the tokens concerned, when known.
    """

    def __init__(self, message: str, *, tokens: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.tokens = tuple(tokens)


class ObjectNotFound(VisionError):
    """The sharpness pipeline found no region that looks like the calibration object in the image."""


def one_line(exc: BaseException) -> str:
    """``RuntimeError: text at runtime.py:312``: an unexpected exception (a bug) and the innermost Python line it
    came from, on one line, for the one stderr line a dying server writes (``aioadept sim``, with or without
    ``--vplus``)."""
    import os
    import traceback

    tb = traceback.extract_tb(exc.__traceback__)
    at = f" at {os.path.basename(tb[-1].filename)}:{tb[-1].lineno}" if tb else ""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}{at}" if text else f"{type(exc).__name__}{at}"
