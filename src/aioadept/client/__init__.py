"""The asyncio client of a robot server (the paper's MasterControlNode ↔ RobotServer link), by role:

- :mod:`~aioadept.client.results`: the values it gives back (``MessageResult``, ``ExecResult``, ...);
- :mod:`~aioadept.client.registry`: ``PendingCalls``, the sans-IO registry of pending messages (IDs, routing
  acks to submissions, failing them all on a lost connection), driven by bytes in unit tests;
- :mod:`~aioadept.client.transport`: the asyncio transport (TCP protocol callback, or a stream reader task);
- :mod:`~aioadept.client.robot`: ``RobotClient``, lifecycle, timeouts, the stop path and the public calls.

Import everything from here: ``from aioadept.client import RobotClient``.
"""

from aioadept.client.registry import PendingCalls, Submission
from aioadept.client.results import (
    ClientState,
    ClientStats,
    CommandResult,
    ExecResult,
    MessageResult,
    Observer,
    SentMessage,
)
from aioadept.client.robot import Connector, RobotClient

__all__ = [
    "ClientState", "ClientStats", "CommandResult", "Connector", "ExecResult", "MessageResult", "Observer",
    "PendingCalls", "RobotClient", "SentMessage", "Submission",
]
