"""The bus's own errors, in one place: what :mod:`aioadept.bus` raises and nothing about who uses it.

::

    BusError                       ZeroMQ/Protobuf failures at the bus edge (aioadept.errors)
    ├─ RequestTimeout (TimeoutError)   no response to a bus request in time
    ├─ BusEncodeError (ValueError)     a value the bus schema cannot carry
    └─ RemoteError                     the peer answered a request with an ``error`` attribute

The bus never raises a user's error type: a vision caller maps a :class:`RemoteError` (or a response's ``error``)
to :class:`~aioadept.errors.VisionError` with :func:`aioadept.vision.responses.raise_for_error`.
"""

from __future__ import annotations

from typing import Any

from aioadept.errors import BusEncodeError, BusError, RequestTimeout

__all__ = ["BusEncodeError", "BusError", "RemoteError", "RequestTimeout"]


class RemoteError(BusError):
    """The peer answered request ``request_id`` with an ``error`` attribute; ``attributes`` are the whole answer."""

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
