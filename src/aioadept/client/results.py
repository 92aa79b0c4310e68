"""The values a :class:`~aioadept.client.RobotClient` gives back: per message, per command, per call.

Frozen, slotted dataclasses; times in their names (``t_send_s``: client loop clock, ``ack.t_done_s``: server
clock). The ``_make_*`` constructors build the same objects as ``__init__`` in a third of the time (see
:func:`aioadept.protocol.messages.fast_constructor`): a result is built per ack on the client's hot path.
"""

from __future__ import annotations

import enum
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Protocol

from aioadept.commands import Command
from aioadept.geometry import Pose
from aioadept.protocol import Ack, Status
from aioadept.protocol.messages import fast_constructor

__all__ = ["ClientState", "ClientStats", "CommandResult", "ExecResult", "MessageResult", "Observer", "SentMessage"]

_UNEXPECTED_MEMORY = 100
_DONE = Status.DONE


@dataclass(frozen=True, slots=True)
class SentMessage:
    """One command message as written (observer ``on_send``). ``t_send_s`` is ``loop.time()`` at the write."""

    id: str
    skill: str
    args: tuple
    batch: int
    t_send_s: float


@dataclass(frozen=True, slots=True)
class MessageResult:
    """One command message and its ack (observer ``on_ack``; element of every result).

    ``t_send_s`` / ``t_recv_s`` are client loop-clock seconds at the write and at the read that delivered the ack;
    the ack's ``t_start_s`` / ``t_done_s`` are server-clock seconds.
    """

    id: str
    skill: str
    args: tuple
    batch: int
    t_send_s: float
    t_recv_s: float
    ack: Ack

    @property
    def status(self) -> Status:
        return self.ack.status

    @property
    def ok(self) -> bool:
        return self.ack.status is _DONE

    @property
    def pose(self) -> Pose:
        return self.ack.pose

    @property
    def rtt_s(self) -> float:
        """Client round trip: read time minus write time (seconds)."""
        return self.t_recv_s - self.t_send_s


@dataclass(frozen=True, slots=True)
class CommandResult:
    """The messages of one command, in the order they were sent."""

    command: Command | None
    messages: tuple[MessageResult, ...]

    @property
    def pose(self) -> Pose:
        """The pose in the last ack (for a motion with break: where the robot came to rest)."""
        return self.messages[-1].ack.pose


@dataclass(frozen=True, slots=True)
class ExecResult:
    """What :meth:`RobotClient.cmdexec` / :meth:`RobotClient.cmdexec_joined` return.

    ``messages``: every message's result in send order; ``commands``: the same grouped per command (built on
    first use, since most callers only look at the last pose).
    """

    messages: tuple[MessageResult, ...]
    sent: tuple[Command | None, ...]
    """The commands, in order."""
    sizes: tuple[int, ...] = field(repr=False)
    """How many messages each command has."""

    @property
    def commands(self) -> tuple[CommandResult, ...]:
        out = []
        i = 0
        for command, n in zip(self.sent, self.sizes, strict=True):
            out.append(CommandResult(command, self.messages[i:i + n]))
            i += n
        return tuple(out)

    @property
    def pose(self) -> Pose:
        """The pose in the last ack."""
        return self.messages[-1].ack.pose

    def __iter__(self) -> Iterator[MessageResult]:
        return iter(self.messages)

    def __len__(self) -> int:
        return len(self.messages)

    def __getitem__(self, index: int) -> MessageResult:
        return self.messages[index]


class ClientState(str, enum.Enum):
    NEW = "new"
    CONNECTED = "connected"
    LOST = "lost"          # the peer closed or the socket failed; connect() again to go on
    CLOSED = "closed"      # close() was called; connect() again to reuse


@dataclass(slots=True)
class ClientStats:
    """Counters of the unusual; all zero on a healthy connection except ``acks``/``messages_sent``."""

    messages_sent: int = 0
    acks: int = 0
    late_acks: int = 0
    """Acks for messages whose waiter was cancelled or timed out (dropped quietly)."""
    unknown_acks: int = 0
    """Acks whose ID was never pending here."""
    unroutable_errors: int = 0
    """``error`` acks with ID ``00000000``: the server could not read an ID from a line we sent."""
    bad_lines: int = 0
    """Lines from the server that do not parse as acks (or are over the length limit)."""
    unexpected: deque = field(default_factory=lambda: deque(maxlen=_UNEXPECTED_MEMORY))
    """The most recent unknown/unroutable/bad lines, as ``(loop_time_s, kind, bytes)``."""


class Observer(Protocol):
    def on_send(self, msg: SentMessage) -> None: ...
    def on_ack(self, result: MessageResult) -> None: ...


_make_exec = fast_constructor(ExecResult, ("messages", "sent", "sizes"))
_make_result = fast_constructor(MessageResult, ("id", "skill", "args", "batch", "t_send_s", "t_recv_s", "ack"))
# The twins behind the constructors, for the hot paths' inline builds (None when the fast build is not in use).
_RESULT_TWIN = getattr(_make_result, "twin", None)
_EXEC_TWIN = getattr(_make_exec, "twin", None)
