"""The settings of a :class:`~aioadept.client.RobotClient`, as one frozen value checked once when it is made.

``RobotClient(host, port, ack_timeout_s=...)`` builds one from its keywords; ``RobotClient(options=opts)`` takes a
ready one (the same settings for several clients, or from a cell file). Every field keeps the meaning of the
keyword of the same name (see :class:`~aioadept.client.RobotClient`). A bad value is a ``ValueError`` naming the
field, before any client exists.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any

from aioadept import defaults
from aioadept.client.registry import check_timeout
from aioadept.protocol import MAX_ACK_LINE

STOP_TIMEOUT_S = 5.0
"""Default ``stop_timeout_s``: a stop is acked at rest, a deceleration ramp away (0.1-0.2 s in the sim)."""


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


@dataclass(frozen=True, slots=True)
class ClientOptions:
    """What a :class:`~aioadept.client.RobotClient` is told when it is made (its keyword arguments, one each)."""

    host: str = defaults.ROBOT_HOST
    port: int = defaults.ROBOT_PORT
    connect_timeout_s: float = 5.0
    ack_timeout_s: float | None = 60.0
    stop_timeout_s: float = STOP_TIMEOUT_S
    observers: tuple[Any, ...] = ()
    id_start: int | None = None
    auto_reconnect: bool = False
    connector: Callable[[], Awaitable[tuple[Any, Any]]] | None = None
    max_line: int = MAX_ACK_LINE
    hello_timeout_s: float | None = None
    stop_side_path: bool = False
    max_pending: int | None = defaults.MAX_QUEUED
    stop_port: int | str | None = "auto"

    def __post_init__(self) -> None:
        port, id_start, max_pending, stop_port = self.port, self.id_start, self.max_pending, self.stop_port
        if not _is_int(port) or not 0 <= port <= 0xFFFF:
            raise ValueError(f"port: {port!r} is not a TCP port number (0..65535)")
        if id_start is not None and (not _is_int(id_start) or not 0 < id_start <= 0xFFFFFFFF):
            raise ValueError(f"id_start: {id_start!r} is not an int in 1..0xFFFFFFFF (00000000 is reserved)")
        if max_pending is not None and (not _is_int(max_pending) or max_pending < 1):
            raise ValueError(f"max_pending: {max_pending!r} is not an int >= 1 (or None: no limit)")
        if stop_port is not None and stop_port != "auto" and (not _is_int(stop_port) or not 0 < stop_port <= 0xFFFF):
            raise ValueError(f"stop_port: {stop_port!r} is not a TCP port number (1..65535), 'auto' or None")
        if not _is_int(self.max_line) or self.max_line < 1:
            raise ValueError(f"max_line: {self.max_line!r} is not an int >= 1")
        # Timeouts as seconds (float), in the order the client has always checked them.
        set_ = object.__setattr__
        set_(self, "connect_timeout_s", check_timeout("connect_timeout_s", self.connect_timeout_s, none_ok=False))
        set_(self, "ack_timeout_s", check_timeout("ack_timeout_s", self.ack_timeout_s))
        set_(self, "stop_timeout_s", check_timeout("stop_timeout_s", self.stop_timeout_s, none_ok=False))
        set_(self, "hello_timeout_s", check_timeout("hello_timeout_s", self.hello_timeout_s))
        set_(self, "observers", tuple(self.observers))

    @property
    def stop_port_number(self) -> int | None:
        """The stop port :meth:`RobotClient.stop` may use: ``port`` + 1 for ``"auto"`` (none for port 0 or
        65535), the number given, or ``None`` (``stop_port=None``, or a ``connector``: no TCP of its own)."""
        if self.stop_port is None or self.connector is not None:
            return None
        if self.stop_port == "auto":
            return self.port + defaults.STOP_PORT_OFFSET if 0 < self.port < 0xFFFF else None
        return int(self.stop_port)
