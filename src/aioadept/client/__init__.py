"""The asyncio client of a robot server (the paper's MasterControlNode ↔ RobotServer link), by role:

- ``client/results.py``: the values it gives back (``MessageResult``, ``ExecResult``, ...);
- ``client/registry.py``: ``PendingCalls``, the sans-IO registry of pending messages (IDs, routing
  acks to submissions, failing them all on a lost connection), driven by bytes in unit tests;
- ``client/transport.py``: the asyncio transport (TCP protocol callback, or a stream reader task);
- ``client/options.py``: ``ClientOptions``, the client's settings as one frozen value, checked once;
- ``client/deadlines.py``: ``DeadlineQueue``, the sans-IO queue behind the one watchdog timer (time passed in);
- ``client/ready.py``: ``ReadyAttempts``, the sans-IO retry schedule of ``wait_ready``;
- ``client/stopport.py``: a stop on the stop port, and the race of the two stop paths (first ``done`` wins);
- ``client/robot.py``: ``RobotClient``, lifecycle, timeouts, the stop flow and the public calls.

Import everything from here: ``from aioadept.client import RobotClient``.
"""

from aioadept.client.options import ClientOptions
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
    "ClientOptions", "ClientState", "ClientStats", "CommandResult", "Connector", "ExecResult", "MessageResult", "Observer",
    "PendingCalls", "RobotClient", "SentMessage", "Submission",
]
