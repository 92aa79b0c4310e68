"""The default addresses of a cell, written once: every subcommand, the cell file and the library read them here.

A cell on one machine (``aioadept demo``) uses these; a node moved to another machine gets its address from
``--config`` or an option. ZeroMQ endpoints are written as the bus reads them (``aioadept.bus.endpoints``).
"""

from __future__ import annotations

ROBOT_HOST = "127.0.0.1"
ROBOT_PORT = 1234
"""The robot server's TCP port (the V+ AdeptServer's, as in pyadept)."""
STATE_ENDPOINT = "tcp://127.0.0.1:5560"
"""Where the sim publishes the robot state stream (the virtual camera subscribes)."""
REQUEST_ENDPOINT = "tcp://127.0.0.1:5555"
"""Vision requests: the MCN's PUB, the node's SUB."""
RESPONSE_ENDPOINT = "tcp://127.0.0.1:5556"
"""Vision responses: the node's PUB, the MCN's SUB."""
