"""ZeroMQ CURVE authentication and encryption for the bus, as an option (off unless a ``curve=`` is given).

Without it anyone who can reach a bus port can subscribe to the robot state and the vision answers, or publish
requests to a vision node (docs/security.md). With it, every connection does a CURVE handshake:

- the **server** side (:class:`CurveServer`; normally the side that binds: the vision node, the sim's state
  stream) holds a key pair and, optionally, the public keys of the clients it accepts;
- the **client** side (:class:`CurveClient`; normally the side that connects: the MasterControlNode, the
  virtual camera) holds its own key pair and the server's public key.

The server side checks client keys through a ZAP handler (pyzmq's :class:`zmq.auth.thread.ThreadAuthenticator`),
one per ZeroMQ context, started with the first secured server socket of that context and stopped with the last.
Each secured server socket gets its own ZAP domain, so two sockets in one process can accept different clients.
A peer without CURVE, with the wrong server key, or with a key not on the list never completes the handshake: it
receives nothing and its messages are dropped. Keys are Z85 text (40 characters), as ``zmq.curve_keypair()``
makes them; :func:`save_keypair` / :func:`load_keypair` use ZeroMQ's certificate files (``zmq.auth``).

Usage::

    server, client = CurveKeyPair.generate(), CurveKeyPair.generate()
    pub = Publisher("tcp://127.0.0.1:*", curve=CurveServer(server, allowed_clients=[client.public]))
    sub = Subscriber(pub.actual_endpoint, curve=CurveClient(client, server_public=server.public))
"""

from __future__ import annotations

import contextlib
import errno
import itertools
import logging
import os
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import zmq
import zmq.auth
from zmq.auth.thread import ThreadAuthenticator

from aioadept.errors import BusError

__all__ = [
    "CurveClient",
    "CurveKeyPair",
    "CurveServer",
    "apply_curve",
    "load_keypair",
    "release",
    "save_keypair",
]

log = logging.getLogger(__name__)


def _key(value: bytes | str, what: str) -> bytes:
    key = value.encode("ascii") if isinstance(value, str) else bytes(value)
    if len(key) != 40:
        raise ValueError(f"{what}: a CURVE key is 40 Z85 characters, got {len(key)}")
    return key


@dataclass(frozen=True, slots=True)
class CurveKeyPair:
    """A CURVE key pair as Z85 text (40 ASCII characters each). ``secret`` may be None for a public-only key."""

    public: bytes
    secret: bytes | None = field(default=None, repr=False)  # never printed

    def __post_init__(self) -> None:
        object.__setattr__(self, "public", _key(self.public, "public"))
        if self.secret is not None:
            object.__setattr__(self, "secret", _key(self.secret, "secret"))

    @classmethod
    def generate(cls) -> CurveKeyPair:
        """A fresh key pair (``zmq.curve_keypair()``)."""
        public, secret = zmq.curve_keypair()
        return cls(public, secret)


@dataclass(frozen=True, slots=True)
class CurveServer:
    """The server role: ``keys`` (with the secret) and the client public keys accepted.

    ``allowed_clients=None`` accepts any client that knows the server's public key (the traffic is still
    encrypted, but there is no client authentication: prefer a list).
    """

    keys: CurveKeyPair
    allowed_clients: frozenset[bytes] | None = None

    def __init__(self, keys: CurveKeyPair, allowed_clients: Iterable[bytes | str] | None = None) -> None:
        if keys.secret is None:
            raise ValueError("CurveServer: keys need the secret key")
        object.__setattr__(self, "keys", keys)
        allowed = None if allowed_clients is None else frozenset(_key(k, "allowed client") for k in allowed_clients)
        object.__setattr__(self, "allowed_clients", allowed)


@dataclass(frozen=True, slots=True)
class CurveClient:
    """The client role: ``keys`` (with the secret) and the public key of the server it connects to."""

    keys: CurveKeyPair
    server_public: bytes

    def __post_init__(self) -> None:
        if self.keys.secret is None:
            raise ValueError("CurveClient: keys need the secret key")
        object.__setattr__(self, "server_public", _key(self.server_public, "server_public"))


Curve = CurveServer | CurveClient


# -- key files ---------------------------------------------------------------------------------------------------

def save_keypair(directory: str | os.PathLike[str], name: str, keys: CurveKeyPair | None = None) -> tuple[Path, Path]:
    """Write ``NAME.key`` (public) and ``NAME.key_secret`` (public + secret, mode 0600) in ZeroMQ's certificate
    format; generate the pair unless given. Returns both paths. Share the ``.key`` file, never the other."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    keys = keys or CurveKeyPair.generate()
    pub_path, sec_path = directory / f"{name}.key", directory / f"{name}.key_secret"
    banner = "#   aioadept CURVE certificate (ZeroMQ zpl format)\n"
    pub_path.write_text(f"{banner}metadata\ncurve\n    public-key = \"{keys.public.decode()}\"\n")
    fd = os.open(sec_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as f:
        assert keys.secret is not None
        f.write(f"{banner}metadata\ncurve\n    public-key = \"{keys.public.decode()}\"\n"
                f"    secret-key = \"{keys.secret.decode()}\"\n")
    return pub_path, sec_path


def load_keypair(path: str | os.PathLike[str]) -> CurveKeyPair:
    """Read a certificate file (``.key``: public only; ``.key_secret``: both). Raises ``ValueError``."""
    try:
        public, secret = zmq.auth.load_certificate(os.fspath(path))
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read CURVE certificate {path}: {exc}") from exc
    return CurveKeyPair(public, secret)


def load_public_keys(paths: Iterable[str | os.PathLike[str]]) -> list[bytes]:
    """The public keys of several certificate files (for ``allowed_clients``)."""
    return [load_keypair(p).public for p in paths]


# -- the ZAP handler, one per context ------------------------------------------------------------------------------

class _Allow:
    """The credentials provider of one ZAP domain (one secured server socket)."""

    def __init__(self, allowed: frozenset[bytes] | None) -> None:
        self.allowed = allowed
        self.denied = 0

    def callback(self, domain: str, key: bytes) -> bool:
        ok = self.allowed is None or key in self.allowed
        if not ok:
            self.denied += 1
            log.warning("CURVE: refused client key %s on %s", key.decode("ascii", "replace"), domain)
        return ok


_lock = threading.Lock()
_auths: dict[int, ThreadAuthenticator] = {}           # by the address of the underlying libzmq context
_secured: dict[int, tuple[int, str]] = {}             # id(socket) -> (context address, ZAP domain)
_domains = itertools.count(1)


def apply_curve(sock: zmq.Socket, curve: Curve | None) -> None:
    """Set the CURVE options on ``sock`` before it binds or connects; for a server, install the ZAP handler.

    Call :func:`release` when the socket is closed. Raises :class:`BusError` if this libzmq lacks CURVE or the
    context already has another ZAP handler.
    """
    if curve is None:
        return
    if not zmq.has("curve"):
        raise BusError("this libzmq has no CURVE support")
    if isinstance(curve, CurveClient):
        sock.setsockopt(zmq.CURVE_SERVERKEY, curve.server_public)
        sock.setsockopt(zmq.CURVE_PUBLICKEY, curve.keys.public)
        sock.setsockopt(zmq.CURVE_SECRETKEY, curve.keys.secret)
        return
    if not isinstance(curve, CurveServer):
        raise TypeError(f"curve: expected CurveServer or CurveClient, got {type(curve).__name__}")
    ctx_addr = sock.context.underlying
    with _lock:
        auth = _auths.get(ctx_addr)
        if auth is None:
            # The authenticator's own sockets are plain ones (socket_class=zmq.Socket), so an asyncio context is
            # fine; ZAP is reached over inproc, which only works within the same libzmq context.
            auth = _start_authenticator(sock.context)
            _auths[ctx_addr] = auth
        domain = f"aioadept-{next(_domains)}"
        auth.configure_curve_callback(domain, credentials_provider=_Allow(curve.allowed_clients))
        _secured[id(sock)] = (ctx_addr, domain)
    sock.setsockopt(zmq.CURVE_SERVER, 1)
    sock.setsockopt(zmq.CURVE_SECRETKEY, curve.keys.secret)
    sock.setsockopt(zmq.CURVE_PUBLICKEY, curve.keys.public)
    sock.setsockopt_string(zmq.ZAP_DOMAIN, domain)


def _start_authenticator(ctx: zmq.Context) -> ThreadAuthenticator:
    # libzmq closes sockets asynchronously (its reaper thread), so the ZAP endpoint of an authenticator that was
    # just stopped may still be bound for a few milliseconds: retry EADDRINUSE for a short while before giving up.
    deadline = time.monotonic() + 2.0
    while True:
        auth = ThreadAuthenticator(ctx, log=log)
        try:
            auth.start()
            return auth
        except zmq.ZMQError as exc:
            with contextlib.suppress(Exception):
                auth.stop()
            if exc.errno != errno.EADDRINUSE or time.monotonic() > deadline:
                raise BusError(f"cannot start the CURVE authenticator (another ZAP handler?): {exc}") from exc
            time.sleep(0.01)


def release(sock: zmq.Socket) -> None:
    """Forget a secured server socket (idempotent; a no-op for others); the last one of a context stops its ZAP
    handler."""
    with _lock:
        entry = _secured.pop(id(sock), None)
        if entry is None:
            return
        ctx_addr, domain = entry
        auth = _auths.get(ctx_addr)
        if auth is None:
            return
        auth.credentials_providers.pop(domain, None)
        if any(c == ctx_addr for c, _ in _secured.values()):
            return
        del _auths[ctx_addr]
    auth.stop()


def denied_count(sock: zmq.Socket) -> int:
    """How many client keys the ZAP handler refused on this secured server socket (0 if not secured)."""
    with _lock:
        entry = _secured.get(id(sock))
        if entry is None:
            return 0
        auth = _auths.get(entry[0])
        provider = auth.credentials_providers.get(entry[1]) if auth is not None else None
        return provider.denied if isinstance(provider, _Allow) else 0
