"""The one exception tree of aioadept: every error the package raises on purpose is defined here.

Errors from sockets, ZeroMQ, Zenoh and Protobuf are translated into these where they enter the library, so user
code catches our types only. An error that is also a builtin one keeps that base (shown in brackets), so an
``except ValueError`` or ``except OSError`` written for it keeps working::

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
    │   ├─ BusEncodeError (ValueError)     a value the bus schema cannot carry
    │   └─ RemoteError                     the peer answered a bus request with an ``error`` attribute
    ├─ VisionError                 a vision node answered with an error result (e.g. no object found)
    │   └─ ObjectNotFound          the sharpness pipeline found no calibration object in the image
    ├─ GraphError (ValueError)     a computational graph is inconsistent or misused
    ├─ BadRequest (ValueError)     a vision node request attribute the node cannot use (answered ``error``)
    ├─ BadLocateRequest (ValueError)   a locate request attribute out of range or of the wrong type
    ├─ RobotError                  the simulated controller refused a motion (reach, joint limit); carries the code
    ├─ ConfigError (ValueError)    a configuration file (or option) that cannot be used; one line naming it
    ├─ RunSaveError (OSError)      some files of a run folder could not be written
    │   └─ AnalysisSaveError       some outputs of an analysis could not be written
    ├─ NodeError                   a node process of the cell failed to start or died
    ├─ FocusError                  focus calibration failed (the robot was sent back to the approach pose)
    │   └─ FocusStopped            a stop event ended the run; the robot was stopped where it was
    ├─ StopFailed                  a stop an application sent was not confirmed: the robot may still be moving
    ├─ PickPlaceError              a pick-and-place run stopped; says whether the failing cycle moved the robot
    ├─ CalibrationError (ValueError)   the camera calibration could not be made
    ├─ MalformedRequest (ValueError)   a query the Zenoh bridge refuses (answered ``malformed``; nothing sent)
    ├─ BridgeRefused               the bridge refused a query (``malformed`` or ``closed``); nothing of it was sent
    ├─ BridgeNameTaken             another bridge holds this robot's name on the Zenoh network
    └─ ViewerUnavailable (RuntimeError)   Rerun is not installed, or its live viewer could not be started

The V+ emulator's errors are AdeptErrors too, defined beside V+'s table of error codes and texts in
:mod:`aioadept.vplus`: ``VPlusError`` (an error of a V+ program: V+'s code and text, where it happened; its
``VPlusRobotError``), ``LoadError`` (a module that did not load, with every problem), ``VSyntaxError`` and
``CompileError`` (one line of it), and its tools' ``DebugError``, ``MonitorError`` and ``LaunchError`` (ValueError).

This module imports nothing of aioadept, so that every layer, the sans-IO protocol core included, can raise
these.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "AbortedBeforeSend", "AckTimeout", "AdeptError", "AnalysisSaveError", "BadLocateRequest", "BadRequest",
    "BridgeNameTaken", "BridgeRefused", "BusEncodeError", "BusError", "CalibrationError", "ClientStateError",
    "CommandAborted", "CommandError", "ConfigError", "ConnectError", "ConnectionLost", "FocusError", "FocusStopped",
    "GraphError", "LocalProtocolError", "MalformedRequest", "NodeError", "NotARobotServer", "ObjectNotFound",
    "PickPlaceError", "ProtocolError", "RemoteError", "RemoteProtocolError", "RequestTimeout", "RobotError",
    "RunSaveError", "StopFailed", "TooManyPending", "ViewerUnavailable", "VisionError",
]


class AdeptError(Exception):
    """Base of every error raised by aioadept."""


# ------------------------------------------------------------------------------------------------- the protocol

class ProtocolError(AdeptError):
    """Bytes on the wire that break the line protocol."""


class LocalProtocolError(ProtocolError):
    """We were asked to encode something the protocol cannot carry (e.g. a line over 128 characters)."""


class RemoteProtocolError(ProtocolError):
    """The peer sent something that does not parse.

    ``code`` is the V+-style error code (see :mod:`aioadept.protocol.codes`) that a server answers with, and ``id``
    the message ID when one could be recovered from the line, so that the error ack can be routed.
    """

    def __init__(self, code: int, message: str, *, id: str | None = None, line: bytes | None = None) -> None:
        super().__init__(f"{message} (code {code})")
        self.code = code
        self.message = message
        self.id = id
        self.line = line


# ------------------------------------------------------------------------------------------------- the client

class CommandError(AdeptError):
    """The server answered a command with an ``error`` ack (``ack``, an :class:`aioadept.protocol.Ack`); the robot
    did not execute it."""

    def __init__(self, ack: Any, skill: str | None = None) -> None:
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

    def __init__(self, ack: Any, skill: str | None = None, *, message: str | None = None) -> None:
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


# ------------------------------------------------------------------------------------------------- the bus

class BusError(AdeptError):
    """A failure at the publish/subscribe edge (ZeroMQ or Protobuf)."""


class RequestTimeout(BusError, TimeoutError):
    """A bus request got no matching response in time."""

    def __init__(self, message: str, *, request_id: str | None = None, **extra: Any) -> None:
        super().__init__(message)
        self.request_id = request_id
        self.extra = extra


class BusEncodeError(BusError, ValueError):
    """A value the bus schema cannot carry: an attribute of another type than str/float/int (bool included, as in
    EPypes), an int outside int32, a missing required field. ``key`` names the offending attribute when there is one.
    """

    def __init__(self, message: str, *, key: str | None = None, value: Any = None) -> None:
        super().__init__(message)
        self.key = key
        self.value = value


class RemoteError(BusError):
    """The peer answered request ``request_id`` with an ``error`` attribute; ``attributes`` are the whole answer.

    The bus never raises a user's error type: a vision caller maps it (or a response's ``error``) to
    :class:`VisionError` with :func:`aioadept.vision.responses.raise_for_error`.
    """

    def __init__(self, message: str, *, request_id: str | None = None, event_type: str | None = None,
                 attributes: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.request_id = request_id
        self.event_type = event_type
        self.attributes = dict(attributes or {})

    @property
    def error(self) -> str:
        """The peer's ``error`` text."""
        return str(self.attributes.get("error", ""))


# ------------------------------------------------------------------------------------------------- vision

class VisionError(AdeptError):
    """A vision node answered a request with an error result (for example: no calibration object found)."""

    def __init__(self, message: str, *, attributes: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.attributes = dict(attributes or {})


class GraphError(AdeptError, ValueError):
    """A computational graph is inconsistent (cycle, token produced twice, missing input) or misused at run time.

    Part of the vision side (:mod:`aioadept.vision.graph`); ``tokens`` names the tokens concerned, when known.
    """

    def __init__(self, message: str, *, tokens: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.tokens = tuple(tokens)


class ObjectNotFound(VisionError):
    """The sharpness pipeline found no region that looks like the calibration object in the image."""


class BadRequest(AdeptError, ValueError):
    """A request attribute a vision node cannot use (answered as an ``error``, never raised to the Responder)."""


class BadLocateRequest(AdeptError, ValueError):
    """A locate request attribute out of its range or of the wrong type (answered as ``error``)."""


# ------------------------------------------------------------------------------------------------- the simulator

class RobotError(AdeptError):
    """The (simulated) controller refused a motion: target out of reach, joint limit, bad value."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(f"{message} (code {code})")
        self.code = code
        self.message = message


# ------------------------------------------------------------------------------------------------- files

class ConfigError(AdeptError, ValueError):
    """A configuration file that cannot be used; the message is one line naming the file and what is wrong."""


class RunSaveError(AdeptError, OSError):
    """Some files of a run folder could not be written (disk full, permission, ...).

    ``written``: file names written; ``not_written``: file name -> reason. Files that were not written keep
    whatever content they had before (none is left truncated).
    """

    def __init__(self, run_dir: str | os.PathLike[str], written: Iterable[str], not_written: Mapping[str, str]) -> None:
        self.run_dir = Path(run_dir)
        self.written = tuple(written)
        self.not_written = dict(not_written)
        parts = "; ".join(f"{name} ({why})" for name, why in self.not_written.items())
        super().__init__(f"run folder {self.run_dir}: not written: {parts}")

    def merged(self, other: RunSaveError) -> RunSaveError:
        return RunSaveError(self.run_dir, (*self.written, *other.written), {**self.not_written, **other.not_written})


class AnalysisSaveError(RunSaveError):
    """Outputs of an analysis that could not be written (disk full, ...); the others were written. ``summary``: the
    analysis itself (a :class:`~aioadept.analysis.report.Summary`, whose ``not_written`` names the same files)."""

    def __init__(self, out_dir: str | os.PathLike[str], written: Iterable[str], not_written: Mapping[str, str], *,
                 summary: Any = None) -> None:
        super().__init__(out_dir, written, not_written)
        self.summary = summary
        parts = "; ".join(f"{name} ({why})" for name, why in self.not_written.items())
        self.args = (f"analysis in {self.run_dir}: not written: {parts}",)


# ------------------------------------------------------------------------------------------------- applications

class NodeError(AdeptError):
    """A node process failed to start or died while the cell was running. ``headline``: what happened, in one line
    (the message may go on with the tail of the node's log)."""

    def __init__(self, message: str, *, headline: str | None = None) -> None:
        super().__init__(message)
        self.headline = headline or message.splitlines()[0]


class FocusError(AdeptError):
    """Focus calibration failed; the robot was sent back to the approach pose (``retracted``)."""

    def __init__(self, message: str, *, sharpness: Sequence[float] = (), retracted: bool = False) -> None:
        super().__init__(message)
        self.sharpness = tuple(sharpness)
        self.retracted = retracted


class FocusStopped(FocusError):
    """A stop event ended the run; the robot was stopped where it was and is NOT moved back."""

    def __init__(self, message: str, *, stop_id: str = "") -> None:
        super().__init__(message)
        self.stop_id = stop_id


class StopFailed(AdeptError):
    """A stop was asked for (a stop event) but the robot did not confirm it: the robot may still be moving.

    Not a :class:`FocusStopped`: the run did not end in a known state. ``__cause__`` is the stop's own error.
    """

    def __init__(self, message: str, *, stop_id: str = "") -> None:
        super().__init__(message)
        self.stop_id = stop_id


class PickPlaceError(AdeptError):
    """A pick-and-place run stopped: ``moved`` says whether the robot was moved in the failing cycle (False for
    every fault found before its first motion: no part, a failed locate, a target outside the workspace)."""

    def __init__(self, message: str, *, moved: bool = False, part: int = 0) -> None:
        super().__init__(message)
        self.moved = moved
        self.part = part


class CalibrationError(AdeptError, ValueError):
    """The calibration could not be made: too few usable views, a failed vision request, a bad pose list."""


# ------------------------------------------------------------------------------------------------- the Zenoh bridge

class MalformedRequest(AdeptError, ValueError):
    """A query the bridge refuses (answered ``malformed``; nothing sent)."""


class BridgeRefused(AdeptError):
    """The bridge refused a query (``malformed``, or ``closed``: shutting down); nothing of it was sent."""

    def __init__(self, message: str, *, kind: str = "malformed") -> None:
        super().__init__(message)
        self.kind = kind


class BridgeNameTaken(AdeptError):
    """Another bridge (or another node) holds this robot's name on the Zenoh network: this one does not serve."""


def one_line(exc: BaseException) -> str:
    """``RuntimeError: text at runtime.py:312``: an unexpected exception (a bug) and the innermost Python line it
    came from, on one line, for the one stderr line a dying server writes (``aioadept sim``, with or without
    ``--vplus``)."""
    import traceback

    tb = traceback.extract_tb(exc.__traceback__)
    at = f" at {os.path.basename(tb[-1].filename)}:{tb[-1].lineno}" if tb else ""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}{at}" if text else f"{type(exc).__name__}{at}"


# ------------------------------------------------------------------------------------------------- the recordings

class ViewerUnavailable(AdeptError, RuntimeError):
    """Rerun is not installed, or its viewer could not be started; the message is one line for the user."""
