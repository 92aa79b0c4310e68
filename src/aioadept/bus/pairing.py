"""Request/response pairing over publish/subscribe: what both sides share, with no sockets.

- ids (:func:`new_request_id`) and response naming (:func:`response_type_for`);
- the values observers and callers see (:class:`Request`, :class:`Response`, :class:`BusObserver`);
- :class:`PendingRegistry`, the one registry of outstanding work by key, used by the requester
  (:class:`~aioadept.bus.communicator.Communicator`: a request waiting for its answer, by id) and by the
  responder (:class:`~aioadept.bus.responder.Responder`: a request queued or in process, by (type, id)).

The registry's rule, on both sides: an entry is added before anything can answer it (before the bytes leave) and
removed on every way out (answered, timed out, failed, cancelled, closed), so ``pending`` never holds a request
nobody can still complete.
"""

from __future__ import annotations

import os
from collections.abc import Hashable, Iterator
from dataclasses import dataclass
from typing import Generic, Protocol, TypeVar

from aioadept.errors import RemoteError
from aioadept.errors import ClientStateError

__all__ = ["BusObserver", "PendingRegistry", "Request", "Response", "new_request_id", "response_type_for"]

ID_LENGTH = 8


def new_request_id() -> str:
    """A fresh request id: 8 random lowercase hex characters, the format of the robot protocol's message IDs
    (``uuid4().hex[:8]``). Drawn from ``os.urandom`` directly: same 32 random bits, a tenth of uuid4's cost."""
    return os.urandom(ID_LENGTH // 2).hex()


def response_type_for(request_type: str) -> str:
    """``"VisionRequest"`` -> ``"VisionResponse"``; a type not ending in ``Request`` gets ``Response`` appended."""
    if request_type.endswith("Request"):
        return request_type[: -len("Request")] + "Response"
    return request_type + "Response"


@dataclass(frozen=True, slots=True)
class Request:
    """A request as published (first time); ``t_send_s`` is ``loop.time()`` at the first publish."""

    id: str
    event_type: str
    attributes: dict
    t_send_s: float


@dataclass(frozen=True, slots=True)
class Response:
    """The response matched to a request; ``t_send_s``/``t_recv_s`` are ``loop.time()`` at first publish/receipt."""

    id: str
    event_type: str
    attributes: dict
    t_send_s: float
    t_recv_s: float

    @property
    def latency_s(self) -> float:
        return self.t_recv_s - self.t_send_s

    @property
    def error(self) -> str | None:
        """The peer's ``error`` attribute (docs/interfaces.md), or None."""
        err = self.attributes.get("error")
        return None if err is None else str(err)

    def raise_for_error(self) -> Response:
        """Raise :class:`~aioadept.errors.RemoteError` (with the attributes) if the peer answered with an
        ``error``; else return self. A vision caller wants :func:`aioadept.vision.responses.raise_for_error` instead, which
        raises :class:`~aioadept.errors.VisionError`."""
        if "error" in self.attributes:
            raise RemoteError(f"{self.event_type} {self.id}: {self.attributes['error']}", request_id=self.id,
                              event_type=self.event_type, attributes=self.attributes)
        return self


class BusObserver(Protocol):
    """Timing hooks (e.g. aioadept.runs.capture). Every method is optional; none may block; exceptions are logged.

    ``on_request`` is called once per request, at its first publish; ``on_republish`` (an aioadept extension) at
    each re-publication of the same id, with that moment as ``t_send_s``; ``on_response`` when it is matched.
    """

    def on_request(self, request: Request) -> None: ...

    def on_republish(self, request: Request) -> None: ...

    def on_response(self, response: Response) -> None: ...


K = TypeVar("K", bound=Hashable)
V = TypeVar("V")


class PendingRegistry(Generic[K, V]):
    """Outstanding entries by key, each added once and removed exactly when it is settled.

    :meth:`add` refuses a key already present (:class:`ClientStateError`): one key, one outstanding entry.
    :meth:`pop` is idempotent, so every exit path may call it; :meth:`drain` empties the registry for a close.
    """

    __slots__ = ("_entries", "what")

    def __init__(self, what: str = "request") -> None:
        self._entries: dict[K, V] = {}
        self.what = what

    def add(self, key: K, value: V) -> V:
        if key in self._entries:
            raise ClientStateError(f"{self.what} id {key!r} is already outstanding")
        self._entries[key] = value
        return value

    def get(self, key: K) -> V | None:
        return self._entries.get(key)

    def pop(self, key: K) -> V | None:
        """Remove ``key`` and return its value (None if it was not there)."""
        return self._entries.pop(key, None)

    def drain(self) -> list[V]:
        """Remove every entry and return their values, oldest first."""
        values = list(self._entries.values())
        self._entries.clear()
        return values

    def keys(self) -> tuple[K, ...]:
        return tuple(self._entries)

    def __contains__(self, key: object) -> bool:
        return key in self._entries

    def __len__(self) -> int:
        return len(self._entries)

    def __iter__(self) -> Iterator[K]:
        return iter(tuple(self._entries))
