"""The schedule of :meth:`RobotClient.wait_ready <aioadept.client.RobotClient.wait_ready>`'s attempts, sans-IO: the
times are passed in, the client makes the connections.

Each attempt gets the time left before the deadline; a failed one is remembered in words (the error then names the
last failure) and the next follows after a pause of 0.05 s, doubling up to ``max_backoff_s``. Once the deadline has
passed, :meth:`ReadyAttempts.begin` raises :class:`~aioadept.errors.ConnectError` saying how many attempts were
made and how the last one failed.
"""

from __future__ import annotations

from aioadept.errors import AckTimeout, ConnectError

__all__ = ["FIRST_BACKOFF_S", "ReadyAttempts"]

FIRST_BACKOFF_S = 0.05
"""The pause after the first failed attempt."""


class ReadyAttempts:
    """Attempts to reach ``where`` (``host:port``, for the error) until ``now + timeout_s``."""

    __slots__ = ("attempts", "backoff_s", "deadline", "last", "max_backoff_s", "timeout_s", "where")

    def __init__(self, where: str, timeout_s: float, max_backoff_s: float, now: float) -> None:
        self.where = where
        self.timeout_s = timeout_s
        self.max_backoff_s = max_backoff_s
        self.deadline = now + timeout_s
        self.backoff_s = FIRST_BACKOFF_S
        self.attempts = 0
        self.last = "none"

    def begin(self, now: float) -> float:
        """Count a new attempt and return the time it has (> 0); ConnectError once the deadline has passed."""
        left = self.deadline - now
        if left <= 0:
            raise ConnectError(f"{self.where} not ready within {self.timeout_s:g} s "
                               f"({self.attempts} attempts; last: {self.last})")
        self.attempts += 1
        return left

    def failed(self, exc: BaseException, *, connected: bool) -> None:
        """The attempt failed with ``exc`` (``connected``: the connection was open when it did)."""
        if isinstance(exc, AckTimeout) or (type(exc) is TimeoutError and connected):
            self.last = "connected, but no answer to hello"
        elif type(exc) is TimeoutError:
            self.last = "no connection before the deadline"
        else:
            self.last = f"{type(exc).__name__}: {exc}"

    def pause(self, now: float) -> float:
        """The pause before the next attempt (never past the deadline); the one after it is twice as long."""
        pause = min(self.backoff_s, max(self.deadline - now, 0.0))
        self.backoff_s = min(self.backoff_s * 2, self.max_backoff_s)
        return pause
