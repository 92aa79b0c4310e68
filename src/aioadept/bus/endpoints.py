"""Endpoint strings in the CZMQ style: who binds and who connects, written into the address.

One parser for every endpoint option (the ``aioadept vision`` / ``focus`` / ``demo`` options, the TOML cell, the
Python API of :mod:`aioadept.bus`):

- ``@tcp://127.0.0.1:5555``: this socket **binds**;
- ``>tcp://127.0.0.1:5555``: this socket **connects**;
- ``tcp://127.0.0.1:5555`` (bare): the role's default. Defaults follow pyadept and EPypes: **publishers bind,
  subscribers connect**. So the MCN binds its request PUB and connects its response SUB, and a vision node connects
  its request SUB and binds its response PUB, as the paper's MasterControlNode (pyadept ``PubSubPair``) and every
  EPypes node do.
- A bare address that can only be bound (port ``0`` or ``*``, or host ``*``) binds whatever the role: connecting to
  it is meaningless, and binding to port 0 is how tests and ``aioadept demo`` get a free port.

An endpoint given to one side of a link describes the other side too: :func:`peer` turns "this side binds X" into
the explicit "connect to X" for the peer (and back). The ``READY`` line of ``aioadept vision`` gives each endpoint
in that peer form, so what it prints can be passed as is to ``aioadept focus --request-endpoint`` or
:class:`~aioadept.bus.Communicator`.

``zenoh:KEY`` (e.g. ``zenoh:aioadept/demo/vision/request``) names a Zenoh key expression instead
(:mod:`aioadept.bus.zenoh`): nobody binds a key, so an ``@``/``>`` prefix is accepted and means nothing there.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from aioadept.errors import BusError

__all__ = ["NONE", "Endpoint", "is_none", "opposite", "parse_endpoint", "peer", "peer_actual", "resolve"]

NONE = "none"
"""The word that turns an optional stream off (``--state-endpoint none``: no robot state stream), in every node."""


def is_none(text: str | None) -> bool:
    """Whether ``text`` turns the stream off: :data:`NONE` (any case) or empty/None."""
    return not text or text.strip().lower() == NONE

_TRANSPORTS = ("tcp", "ipc", "inproc", "pgm", "epgm", "ws", "wss", "vmci", "udp")
_ADDRESS = re.compile(r"^(?P<transport>[a-z]+)://(?P<rest>.+)$")


@dataclass(frozen=True, slots=True)
class Endpoint:
    """A parsed endpoint: ``address`` (ZeroMQ form, no prefix) and ``mode``: ``"bind"``, ``"connect"`` or None
    (bare: the role decides)."""

    address: str
    mode: str | None = None

    @property
    def zenoh(self) -> bool:
        """Whether this names a Zenoh key (``zenoh:KEY``) rather than a ZeroMQ address."""
        return self.address.startswith("zenoh:")

    @property
    def only_bindable(self) -> bool:
        """Port 0 / ``*`` or host ``*``: an address one can bind but never connect to."""
        if not self.address.startswith("tcp://"):
            return False
        host, _, port = self.address[len("tcp://"):].rpartition(":")
        return port in ("0", "*") or host == "*"

    def binds(self, default_bind: bool) -> bool:
        """Whether a socket given this endpoint binds, ``default_bind`` being its role's default."""
        if self.mode is not None:
            return self.mode == "bind"
        return True if self.only_bindable else default_bind

    def explicit(self, default_bind: bool) -> str:
        """The same endpoint with its prefix written out (``@…`` or ``>…``)."""
        return ("@" if self.binds(default_bind) else ">") + self.address

    def __str__(self) -> str:
        return {"bind": "@", "connect": ">", None: ""}[self.mode] + self.address


def parse_endpoint(text: str) -> Endpoint:
    """Parse ``[@|>]transport://address``; raises :class:`BusError` with the reason on anything else."""
    if not isinstance(text, str):
        raise BusError(f"endpoint must be a string, got {type(text).__name__}")
    s = text.strip()
    mode: str | None = None
    if s[:1] == "@":
        mode, s = "bind", s[1:]
    elif s[:1] == ">":
        mode, s = "connect", s[1:]
    if s.startswith("zenoh:"):
        from aioadept.bus.zenoh import key_of  # imports no Zenoh: checks the key's spelling only

        key_of(s)
        return Endpoint(s, mode)
    if "," in s:
        raise BusError(f"endpoint {text!r}: one address per endpoint (no comma-separated lists)")
    m = _ADDRESS.match(s)
    if m is None:
        raise BusError(f"endpoint {text!r}: expected [@|>]transport://address, e.g. '@tcp://127.0.0.1:5556' "
                       "(@ binds, > connects, bare: publishers bind and subscribers connect), or zenoh:KEY")
    if m["transport"] not in _TRANSPORTS:
        raise BusError(f"endpoint {text!r}: unknown transport {m['transport']!r}; use one of {_TRANSPORTS}")
    ep = Endpoint(s, mode)
    if mode == "connect" and ep.only_bindable:
        raise BusError(f"endpoint {text!r}: cannot connect to a wildcard host or port 0; give the peer's real "
                       "address, or bind with '@'")
    return ep


def resolve(text: str, default_bind: bool) -> tuple[str, bool]:
    """``(address, bind)`` for a socket given endpoint ``text`` whose role binds by default iff ``default_bind``."""
    ep = parse_endpoint(text)
    return ep.address, ep.binds(default_bind)


def peer(text: str, default_bind: bool) -> str:
    """The explicit endpoint the *other* side of the link uses, given this side's ``text`` and role default: if
    this side binds X, the peer gets ``>X``; if it connects to X, the peer gets ``@X``."""
    ep = parse_endpoint(text)
    if ep.zenoh:
        return ep.address  # a key has no sides
    return (">" if ep.binds(default_bind) else "@") + ep.address


def opposite(text: str) -> str:
    """The same link seen from the other side: ``@X`` <-> ``>X``; a bare address stays bare (the role defaults of
    the two sides are complementary, so a bare address names the same link from either side)."""
    ep = parse_endpoint(text)
    if ep.zenoh:
        return ep.address
    return {"bind": ">", "connect": "@", None: ""}[ep.mode] + ep.address


def peer_actual(text: str, default_bind: bool, actual: str) -> str:
    """:func:`peer` for a socket opened on ``text`` whose endpoint in use is ``actual`` (the real port after binding
    to port 0): the peer connects to ``actual`` if this side bound, else binds it."""
    ep = parse_endpoint(text)
    if ep.zenoh:
        return actual
    return (">" if ep.binds(default_bind) else "@") + actual
