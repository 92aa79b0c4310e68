"""The default addresses of a cell, written once: every subcommand, the cell file and the library read them here.

A cell on one machine (``aioadept demo``) uses these; a node moved to another machine gets its address from
``--config`` or an option. ZeroMQ endpoints are written as the bus reads them (``aioadept.bus.endpoints``).
"""

from __future__ import annotations

ROBOT_HOST = "127.0.0.1"
ROBOT_PORT = 1234
"""The robot server's TCP port (the V+ AdeptServer's, as in pyadept)."""
STOP_PORT_OFFSET = 1
"""The stop port is the robot port + 1 (1235 beside 1234): a second TCP port that serves only ``stop``, ``here`` and
``hello``, so a stop gets in with every client slot taken (``rs.sport`` in ``vplus/rsconfig.V2``, ``aioadept sim
--stop-port``; ``RobotClient(stop_port=...)`` uses it by itself; docs/protocol.md 4.2.1)."""
STOP_PORT = ROBOT_PORT + STOP_PORT_OFFSET
MAX_QUEUED = 64
"""Commands one connection may have pending on a robot server (sent and not yet answered, the running one
included): ``aioadept sim --max-queued`` and the shipped V+ server's ``rs.maxq`` admit this many and refuse more
with -530 as each line is read; ``RobotClient(max_pending=...)`` counts the same way and keeps below it."""
STATE_ENDPOINT = "tcp://127.0.0.1:5560"
"""Where the sim publishes the robot state stream (the virtual camera subscribes)."""
REQUEST_ENDPOINT = "tcp://127.0.0.1:5555"
"""Vision requests: the MCN's PUB, the node's SUB."""
RESPONSE_ENDPOINT = "tcp://127.0.0.1:5556"
"""Vision responses: the node's PUB, the MCN's SUB."""
STATE_STREAM_PORT = 1236
"""The V+ server's state-stream TCP port (``rs.stport`` in vplus/rsconfig.V2), which ``aioadept state`` reads."""
TRANSPORTS = ("zeromq", "zenoh")
"""The bus transports (``--transport``, the cell file's ``[bus] transport``): ZeroMQ is the default and the paper's
wire; Zenoh needs the ``[zenoh]`` extra (docs/bus.md)."""
