"""Pick a TCP port to hand to a node before it binds, outside the kernel's ephemeral range.

A port the OS picks with ``bind(port 0)`` lies in the ephemeral range, where the next outgoing connection of any
process may take it before the node binds it (its ``TIME_WAIT`` then blocks the bind for a minute, even with
``SO_REUSEADDR``). Ports below that range are never handed out to outgoing connections, so only another listener
can take one, and a random pick makes two pickers colliding unlikely.
"""

from __future__ import annotations

import contextlib
import random
import socket
from pathlib import Path

_RANGE_FILE = Path("/proc/sys/net/ipv4/ip_local_port_range")
_LOWEST = 10000


def _ephemeral_range() -> tuple[int, int]:
    try:
        lo, hi = (int(x) for x in _RANGE_FILE.read_text().split())
    except (OSError, ValueError):
        return 49152, 65535  # IANA's dynamic range: macOS, Windows and BSD use it
    return lo, hi


def _candidates() -> range:
    lo, hi = _ephemeral_range()
    if lo - _LOWEST >= 2000:
        return range(_LOWEST, lo)
    return range(hi + 1, 65536) if 65535 - hi >= 2000 else range(1024, 65536)


def _bindable(host: str, port: int) -> bool:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with contextlib.closing(socket.socket(family, socket.SOCK_STREAM)) as s:
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port on ``host`` that was free a moment ago and that no outgoing connection will take."""
    pool = _candidates()
    for _ in range(200):
        port = random.choice(pool)  # noqa: S311 - spreading picks, not a secret
        if _bindable(host, port):
            return port
    with contextlib.closing(socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET)) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])
