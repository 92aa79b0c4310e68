"""Public test doubles of aioadept, the same ones its own tests use.

- :func:`stream_pair` / :class:`memory_connector`: connected asyncio streams in memory (no sockets), optionally
  fragmenting every write, for unit tests of anything built on streams.
- :class:`ScriptedServer`: a robot server on 127.0.0.1 (port 0) that acks per a script (done / error / aborted,
  delays, silence, dropped connections) and records what went over the wire; ``server.connector()`` runs the same
  script in memory.

The running simulated controller (``aioadept.testing.sim``) is provided by the sim package.
"""

from aioadept.testing.scripted import Connection, Event, Reply, ScriptedServer
from aioadept.testing.streams import MemoryTransport, memory_connector, stream_pair

__all__ = ["Connection", "Event", "MemoryTransport", "Reply", "ScriptedServer", "memory_connector", "stream_pair"]
