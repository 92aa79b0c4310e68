"""The default addresses of a cell, written once: every subcommand, the cell file and the library read them here.

A cell on one machine (``aioadept demo``) uses these; a node moved to another machine gets its address from
``--config`` or an option. ZeroMQ endpoints are written as the bus reads them (``aioadept.bus.endpoints``).
"""

from __future__ import annotations

ROBOT_HOST = "127.0.0.1"
ROBOT_PORT = 1234
"""The robot server's TCP port (the V+ AdeptServer's, as in pyadept)."""
MAX_QUEUED = 64
"""Commands one connection may have queued on a robot server: ``aioadept sim --max-queued`` and the shipped V+
server's ``rs.maxq`` admit this many and refuse more with -530; ``RobotClient(max_pending=...)`` keeps below it."""
STATE_ENDPOINT = "tcp://127.0.0.1:5560"
"""Where the sim publishes the robot state stream (the virtual camera subscribes)."""
REQUEST_ENDPOINT = "tcp://127.0.0.1:5555"
"""Vision requests: the MCN's PUB, the node's SUB."""
RESPONSE_ENDPOINT = "tcp://127.0.0.1:5556"
"""Vision responses: the node's PUB, the MCN's SUB."""
STATE_STREAM_PORT = 1235
"""The V+ server's state-stream TCP port (``rs.stport`` in vplus/rsconfig.V2), which ``aioadept state`` reads."""
