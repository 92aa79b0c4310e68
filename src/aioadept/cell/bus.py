"""The cell file's ``[bus]`` table and what follows from it: which transport carries the vision requests and the
robot state (ZeroMQ, the default and the paper's wire, or Eclipse Zenoh), the cell's Zenoh key expressions, the
options a started node gets, and the starter's own Zenoh session (docs/bus.md, "Zenoh, the second transport").
"""

from __future__ import annotations

import contextlib
import dataclasses
from dataclasses import dataclass
from typing import Any

from aioadept.defaults import TRANSPORTS

__all__ = ["BusSection", "check_chunk", "on_cell_key", "transport_argv", "with_transport", "zenoh_session"]


@dataclass(slots=True)
class BusSection:
    """The cell file's ``[bus]`` table: which transport carries the vision requests and the robot state
    (docs/bus.md). ZeroMQ (the default) uses the endpoints of ``[robot]`` and ``[vision]`` as written; with
    ``transport = "zenoh"`` every endpoint left as a ZeroMQ address becomes the cell's key expression
    ``aioadept/<cell>/<node>/<topic>``, and the processes meet at ``zenoh_router``."""

    transport: str = "zeromq"
    """``zeromq`` or ``zenoh`` (the [zenoh] extra)."""
    cell: str = "demo"
    """The cell's name in the Zenoh key expressions (one key chunk)."""
    zenoh_router: str = "tcp/127.0.0.1:7447"
    """``tcp/HOST:PORT`` of the Zenoh router (port 0 with ``start_router``: a free one)."""
    start_router: bool = True
    """The starter (``aioadept demo``/``focus``) is the router, listening on ``zenoh_router``; false: connect to a
    router that runs elsewhere."""
    zenoh_config: str = ""
    """A Zenoh configuration file (JSON5) every process of the cell opens its session with: credentials, TLS,
    access control (:attr:`aioadept.bus.zenoh.ZenohOptions.config_file`; docs/security.md). Relative to the cell
    file. Empty: none."""
    zenoh_queries: bool = False
    """With ``transport = "zenoh"``: the application asks the vision node with Zenoh queries (each answer the reply
    to its query) instead of publications on the request and response keys. The node answers both; publications
    cost less (docs/bus.md, "Requests: publications or Zenoh queries")."""

    def check(self, where: str) -> None:
        """ValueError naming the key for a value out of its choices."""
        if self.transport not in TRANSPORTS:
            raise ValueError(f"transport = {self.transport!r}: expected one of {', '.join(TRANSPORTS)}")
        from aioadept.bus import zenoh as zb
        from aioadept.errors import BusError

        try:
            check_chunk(self.cell, "cell", sep=" = ")
        except BusError as exc:
            raise ValueError(str(exc)) from None
        host_port = self.zenoh_router.rpartition(":")
        try:
            if host_port[2] == "0" and self.start_router:
                zb.check_locator(host_port[0] + ":1")  # a free port is picked at start
            else:
                zb.check_locator(self.zenoh_router)
        except BusError as exc:
            raise ValueError(f"zenoh_router: {exc}") from None
        if self.zenoh_config and self.zenoh:
            try:
                zb.ZenohOptions.client(config_file=self.zenoh_config)  # loads it: one line now, not at start
            except BusError as exc:
                raise ValueError(f"zenoh_config: {exc}") from None

    def options(self, *, router: bool) -> Any:
        """This cell's :class:`~aioadept.bus.zenoh.ZenohOptions`: the router's (listening on ``zenoh_router``) or
        a client's of it, with ``zenoh_config``."""
        from aioadept.bus import zenoh as zb

        config = self.zenoh_config or None
        return (zb.ZenohOptions.router(self.zenoh_router, config_file=config) if router
                else zb.ZenohOptions.client(self.zenoh_router, config_file=config))

    @property
    def zenoh(self) -> bool:
        return self.transport == "zenoh"


def check_chunk(value: str, name: str, *, sep: str = " ") -> str:
    """``value`` if it is one chunk of a Zenoh key (a cell's or a node's name: letters, digits, ``_ . -``); raises
    :class:`~aioadept.errors.BusError` naming it: ``--cell 'a/b': one key chunk ...`` (``sep=" = "``: a file's
    key)."""
    from aioadept.bus.zenoh import check_key
    from aioadept.errors import BusError

    try:
        if "/" not in value:
            return check_key(value)
    except BusError:
        pass
    raise BusError(f"{name}{sep}{value!r}: one key chunk (letters, digits, '_', '.', '-'), no '/'")


def with_transport(cfg: Any) -> Any:
    """``cfg`` with ``[bus] transport = "zenoh"`` applied: every endpoint that is a ZeroMQ address becomes the
    cell's key (``zenoh:aioadept/<cell>/sim/state``, ``.../vision/request``, ``.../vision/response``); a
    ``zenoh:`` endpoint or ``none`` is kept. The same ``cfg`` on ZeroMQ."""
    if not cfg.bus.zenoh:
        return cfg
    cfg = dataclasses.replace(cfg, robot=dataclasses.replace(cfg.robot), vision=dataclasses.replace(cfg.vision))
    for section, name, owner, topic in ((cfg.robot, "state_endpoint", "sim", "state"),
                                        (cfg.vision, "request_endpoint", "vision", "request"),
                                        (cfg.vision, "response_endpoint", "vision", "response")):
        setattr(section, name, on_cell_key(getattr(section, name), cfg.bus.cell, owner, topic))
    return cfg


def on_cell_key(endpoint: str, cell: str, owner: str, topic: str) -> str:
    """The endpoint a Zenoh cell uses for the stream ``owner``/``topic`` written ``endpoint`` in its file: a ZeroMQ
    address becomes the cell's key ``zenoh:aioadept/<cell>/<owner>/<topic>``; a ``zenoh:`` endpoint or ``none`` is
    kept. The one rule of the starter (:func:`with_transport`) and of a node reading the file itself
    (:func:`aioadept.cli.options.apply_cell_bus`), so both meet on the same keys."""
    from aioadept.bus.endpoints import is_none
    from aioadept.bus.zenoh import endpoint_for, is_zenoh

    if is_none(endpoint) or is_zenoh(endpoint):
        return endpoint
    return endpoint_for(cell, owner, topic)


def transport_argv(cfg: Any) -> list[str]:
    """The ``--transport`` options a node of ``cfg`` is started with (none on ZeroMQ)."""
    if not cfg.bus.zenoh:
        return []
    argv = ["--transport", "zenoh", "--cell", cfg.bus.cell, "--zenoh-connect", cfg.bus.zenoh_router]
    return argv + (["--zenoh-config", cfg.bus.zenoh_config] if cfg.bus.zenoh_config else [])


@contextlib.contextmanager
def zenoh_session(cfg: Any, node: str = "app"):
    """For a Zenoh cell: this process's session (the router when ``start_router``, else a client of it), declared
    as node ``node``, closed on exit. Nothing on ZeroMQ."""
    if not cfg.bus.zenoh:
        yield
        return
    from aioadept.bus import zenoh as zb

    zb.configure(cfg.bus.options(router=cfg.bus.start_router))
    try:
        zb.declare_node(cfg.bus.cell, node)
        yield
    finally:
        zb.close_session()
