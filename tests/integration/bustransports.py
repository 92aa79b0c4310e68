"""The bus tests' transports: the same test runs over ZeroMQ and over Zenoh.

A test that takes the ``bus`` fixture (``tests/integration/conftest.py``) runs once per transport (and once more on
Zenoh with requests sent as queries) and asks it for
endpoints instead of writing ``tcp://`` addresses:

- ``bus.any()``: a fresh endpoint the first side opens (ZeroMQ: ``tcp://127.0.0.1:*``, the OS picks the port;
  Zenoh: a fresh key ``aioadept/test/<run>/<n>``);
- ``bus.fixed()``: an address known before anybody opens it (a node started later, or restarted, on the same one);
- ``bus.nowhere()``: an address nobody serves.

Zenoh runs in this test process as a router listening on a free loopback port (multicast scouting and gossip
off), so every publisher and subscriber of the test meets through it; nothing leaves 127.0.0.1.
"""

from __future__ import annotations

import itertools
import os
from aioadept.ports import free_port

TRANSPORTS = ("zeromq", "zenoh", "zenoh-queries")
"""``zenoh-queries``: Zenoh with every Communicator sending its requests as queries (``queries=True``), so the whole
pairing contract is tested on that path too (docs/bus.md, "Requests: publications or Zenoh queries")."""

_run = os.urandom(4).hex()
_counter = itertools.count()


class BusEndpoints:
    def __init__(self, name: str) -> None:
        self.name = name

    @property
    def zenoh(self) -> bool:
        return self.name.startswith("zenoh")

    def any(self) -> str:
        if self.zenoh:
            return f"zenoh:aioadept/test/{_run}/{next(_counter)}"
        return "tcp://127.0.0.1:*"

    def fixed(self) -> str:
        return self.any() if self.zenoh else f"tcp://127.0.0.1:{free_port()}"

    def nowhere(self) -> str:
        return self.any() if self.zenoh else "tcp://127.0.0.1:1"

    def __repr__(self) -> str:
        return self.name


_router: str | None = None


def start_zenoh_router() -> str:
    """Configure this process's Zenoh session as a loopback router (once per process); returns where it listens
    (``tcp/127.0.0.1:PORT``), for node processes to ``--zenoh-connect`` to."""
    global _router
    if _router is None:
        from aioadept.bus import zenoh as zb

        router = f"tcp/127.0.0.1:{free_port()}"
        zb.configure(zb.ZenohOptions.router(router))
        zb.session()
        _router = router
    return _router
