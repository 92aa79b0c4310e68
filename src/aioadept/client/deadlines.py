"""The client's deadline watchdog, sans-IO: waits that share the default timeout, watched by one timer.

A timer per wait costs ~10-30 us of loop time per round trip on a small VM. Deadlines of one constant timeout come
in the order the waits began, so one queue in deadline order and one timer (at its front's deadline) serve them
all. This module keeps the queue and says which waits are due at a time it is given; the owner
(:class:`~aioadept.client.RobotClient`) keeps the one timer and times the waits out.

An item is any object with a ``_deadline`` (float, set here) and a ``_settled`` flag (set by its owner once the
wait is over: such an item is dropped, never reported due).
"""

from __future__ import annotations

from collections import deque
from typing import Any

__all__ = ["DeadlineQueue"]


class DeadlineQueue:
    """Waits in deadline order. ``push`` refuses a wait whose deadline would come before the last one's (a
    changed default): that wait needs a timer of its own."""

    __slots__ = ("_queue",)

    def __init__(self) -> None:
        self._queue: deque[Any] = deque()

    def __len__(self) -> int:
        return len(self._queue)

    def push(self, item: Any, deadline: float) -> bool:
        """Queue ``item`` to be due at ``deadline``; False (nothing queued) if that is before the last queued
        deadline."""
        queue = self._queue
        while queue and queue[0]._settled:  # finished waits leave from the front (batches finish roughly in order)
            queue.popleft()
        if queue and queue[-1]._deadline > deadline:
            return False
        item._deadline = deadline
        queue.append(item)
        return True

    @property
    def next_deadline(self) -> float | None:
        """When the timer should next fire (the front's deadline); None: nothing queued."""
        return self._queue[0]._deadline if self._queue else None

    def due(self, now: float) -> list[Any]:
        """Take out and return the unsettled waits whose deadline is ``now`` or earlier, in order (settled ones on
        the way are dropped)."""
        queue = self._queue
        out = []
        while queue:
            item = queue[0]
            if not item._settled and item._deadline > now:
                break
            queue.popleft()
            if not item._settled:
                out.append(item)
        return out

    def clear(self) -> None:
        self._queue.clear()
