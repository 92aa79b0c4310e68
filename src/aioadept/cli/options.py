"""The options layer every subcommand shares: the help formatter, ``--config``, ``-v``, the robot address, the
ZeroMQ endpoints with their defaults (read from :mod:`aioadept.defaults`, never spelled out here), the cell options of
``demo``/``focus``/``experiment``, logging, and the one error-to-one-line handler (:func:`report`, the config
reader's).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from aioadept import defaults
from aioadept.errors import ConfigError

if TYPE_CHECKING:
    from aioadept.cell.config import CellConfig
    from aioadept.cell.bus import BusSection

__all__ = [
    "ArgumentParser", "DefaultsHelpFormatter", "Listener", "ROBOT_HELP", "add_cell_options", "add_config",
    "add_insecure_option", "add_verbose", "apply_cell_bus", "apply_overrides", "check_listeners",
    "check_option", "configure_logging", "description", "is_loopback", "option_help", "parse_robot_address",
    "zenoh_authenticates"
]


def description(doc: str | None) -> str:
    """A module docstring's first paragraph as a subcommand's ``--help`` shows it: without ````literal```` markup."""
    return (doc or "").split("\n\n")[0].replace("``", "")


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser with a mistake reported in one line on stderr (``PROG: error: MESSAGE``, exit 2), without
    the usage block argparse prints first: every subcommand's bad option reads like its bad config value."""

    def error(self, message: str):  # type: ignore[override]  # noqa: ANN201
        import re

        # "argument --x: ..." names the option; its form (the usage argparse no longer prints) follows the message.
        m = re.match(r"argument ([^/:\s]+)", message)
        action = self._option_string_actions.get(m.group(1)) if m else None
        form = ""
        if action is not None and action.nargs != 0:
            form = f"{m.group(1)} {action.metavar or action.dest.upper()}; "  # type: ignore[union-attr]
        self.exit(2, f"{self.prog}: error: {message} ({form}see {self.prog} --help)\n")


class DefaultsHelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Adds "(default: X)" to an option's help unless the help already says its default, or there is none."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "default" in text or action.default in (None, False, [], argparse.SUPPRESS):
            return text
        return super()._get_help_string(action)


def add_config(p: argparse.ArgumentParser, help: str, **kw) -> None:  # noqa: A002
    """``--config FILE``: a TOML file read with :func:`aioadept.cell.schema.load_toml`."""
    p.add_argument("--config", metavar="FILE", help=help, **kw)


def add_verbose(p: argparse.ArgumentParser) -> None:
    p.add_argument("-v", "--verbose", action="store_true")


ROBOT_HELP = (f"robot server HOST[:PORT] (default {defaults.ROBOT_HOST}:{defaults.ROBOT_PORT}; without a port: "
              f"{defaults.ROBOT_PORT})")


def parse_robot_address(text: str, default_port: int = defaults.ROBOT_PORT) -> tuple[str, int]:
    """``"HOST[:PORT]"`` -> ``(host, port)``; the port defaults to :data:`aioadept.defaults.ROBOT_PORT`;
    ValueError in one line otherwise."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = text, str(default_port)
    if not port.isdigit() or not 0 < int(port) <= 0xFFFF:
        raise ValueError(f"--robot {text!r}: expected HOST[:PORT] with PORT in 1..65535, "
                         f"e.g. {defaults.ROBOT_HOST}:{defaults.ROBOT_PORT}")
    return host or defaults.ROBOT_HOST, int(port)


_FOCUS_OPTIONS = (("speed", "approach_speed"), ("delta_z", "delta_z_mm"), ("max_steps", "max_steps"),
                  ("vision_timeout", "vision_timeout_s"))
"""The cell options that set a :class:`~aioadept.apps.focus.FocusParams` field: (argparse dest, field)."""


def option_help(text: str, cls: type, name: str) -> str:
    """An option's help ending in the range and default of dataclass field ``cls.name``, both read from the field
    (:func:`aioadept.cell.schema.range_of`), so ``--help`` says what the check enforces."""
    from aioadept.cell.schema import range_of

    default = next(f.default for f in dataclasses.fields(cls) if f.name == name)
    return f"{text} ({range_of(cls, name).text}; default {default:g})".replace("%", "%%")  # argparse expands %


def add_cell_options(p: argparse.ArgumentParser) -> None:
    from aioadept.apps.focus import FocusParams

    add_config(p, "cell description (TOML); options below override it", type=Path)
    p.add_argument("--out", metavar="DIR", help="folder for run folders (default: runs)")
    p.add_argument("--speed", type=int, help=option_help("approach speed", FocusParams, "approach_speed"))
    p.add_argument("--delta-z", type=float, dest="delta_z", metavar="MM",
                   help=option_help("tool z step", FocusParams, "delta_z_mm"))
    p.add_argument("--max-steps", type=int, dest="max_steps",
                   help=option_help("give up after this many steps", FocusParams, "max_steps"))
    p.add_argument("--vision-timeout", type=float, dest="vision_timeout",
                   help=option_help("seconds per vision request", FocusParams, "vision_timeout_s"))
    p.add_argument("--no-analyze", action="store_true", help="do not compute the timing analysis and plots")
    add_transport_option(p)
    add_verbose(p)
    from aioadept.record.hook import add_view_options

    add_view_options(p)


def add_mode_option(p: argparse.ArgumentParser) -> None:
    """``--mode stepwise|sweep`` (``aioadept focus``, ``aioadept demo``): the cell file's ``[focus] mode``."""
    from aioadept.apps.sweep import MODES

    p.add_argument("--mode", choices=MODES, default=None,
                   help="stepwise: the paper's loop, a frame at every delta-z step (the default); sweep: one "
                        "straight-line motion with frames on the way and a fit of the sharpness peak "
                        "(docs/focus.md)")


def check_option(option: str, cls: type, name: str, value: object) -> None:
    """ValueError ``"--OPTION VALUE: expected ..."`` unless ``value`` is in the range of field ``cls.name``."""
    from aioadept.cell.schema import range_of

    range_of(cls, name).check(option, value, sep=" ")


def apply_overrides(cfg: "CellConfig", args: argparse.Namespace) -> "CellConfig":
    """The cell options of ``args`` applied to ``cfg``; ValueError naming the option for a value out of its range
    (checked here, before anything starts)."""
    from aioadept.apps.focus import FocusParams

    changes = {}
    for dest, name in _FOCUS_OPTIONS:
        value = getattr(args, dest)
        if value is not None:
            check_option("--" + dest.replace("_", "-"), FocusParams, name, value)
            changes[name] = value
    mode = getattr(args, "mode", None)
    if mode is not None:
        changes["mode"] = mode
    cfg.focus = dataclasses.replace(cfg.focus, **changes)
    from aioadept.apps.cell import sim_time_scale
    from aioadept.apps.sweep_plan import check_sweep

    # A sweep the exposure cannot allow: one line, nothing started. Checked here, after --mode and --time-scale,
    # not when the file is read: the file's mode or exposure may be overridden.
    check_sweep(cfg.focus, cfg.vision.exposure_ms, sim_time_scale(cfg))
    if args.out:
        cfg.run.out_dir = args.out
    if args.no_analyze:
        cfg.run.analyze = False
    if getattr(args, "no_record", False):
        cfg.run.record = False
    if getattr(args, "transport", None):
        cfg.bus.transport = args.transport
    return cfg


NODE_LOG_FORMAT = "%(asctime)s %(name)s %(levelname)s %(message)s"
"""The log line of the node commands (sim, state, vision, bridge, ros2) on stderr."""

OWN_LOGGERS = ("aioadept", "__main__", "root")
"""Loggers whose records pass at any level; every other library's pass from WARNING up (:func:`setup_logging`)."""


def _own_or_warning(record: logging.LogRecord) -> bool:
    return record.levelno >= logging.WARNING or record.name.split(".", 1)[0] in OWN_LOGGERS


def setup_logging(level: int | str, *, fmt: str = NODE_LOG_FORMAT, rich: bool = False) -> None:
    """The one logging setup of every command: ``level`` (a number or a name) for aioadept's own records, on stderr
    (``rich``: a :class:`rich.logging.RichHandler` on rich's console); other libraries' records below WARNING are dropped, so ``-v``
    shows this project's DEBUG lines, not matplotlib's font search or asyncio's selector."""
    if rich:
        from rich.logging import RichHandler

        handler: logging.Handler = RichHandler(show_path=False)
    else:
        handler = logging.StreamHandler(sys.stderr)
    handler.addFilter(_own_or_warning)
    logging.basicConfig(level=level.upper() if isinstance(level, str) else level, format=fmt, handlers=[handler])


def configure_logging(verbose: bool) -> None:
    setup_logging(logging.DEBUG if verbose else logging.INFO, fmt="%(message)s", rich=True)


def with_default(text: str, default: object) -> str:
    """An option's help ending in its default, for options whose default is applied later (a config file may set
    it), so argparse cannot show it: ``with_default("SUB for ...", defaults.REQUEST_ENDPOINT)``."""
    return f"{text} (default {default})"


def add_robot_option(p: argparse.ArgumentParser) -> None:
    """``--robot HOST[:PORT]``, read with :func:`parse_robot_address`."""
    p.add_argument("--robot", metavar="HOST[:PORT]", help=ROBOT_HELP)


TRANSPORTS = defaults.TRANSPORTS

_ZENOH_OPTIONS = ("cell", "zenoh_connect", "zenoh_listen", "zenoh_config", "node")


def add_transport_option(p: argparse.ArgumentParser) -> None:
    """``--transport zeromq|zenoh`` (default: the cell file's, else zeromq)."""
    p.add_argument("--transport", choices=TRANSPORTS,
                   help="bus transport: zeromq (default; the paper's wire) or zenoh (the [zenoh] extra; docs/bus.md)")


def add_zenoh_config_option(p: argparse.ArgumentParser, prefix: str = "") -> None:
    """``--zenoh-config FILE``: the Zenoh configuration file the session opens with (credentials, TLS, access
    control; :attr:`aioadept.bus.zenoh.ZenohOptions.config_file`)."""
    p.add_argument("--zenoh-config", metavar="FILE", dest="zenoh_config",
                   help=prefix + "a Zenoh configuration file (JSON5) for credentials, TLS, access control; "
                                 "scouting stays off whatever it says (docs/security.md)")


def add_zenoh_session_options(p: argparse.ArgumentParser, prefix: str = "", router: str = "") -> None:
    """``--zenoh-connect``, ``--zenoh-listen`` and ``--zenoh-config``: where this process's Zenoh session meets the
    cell (read back with :func:`zenoh_session_options`). ``router`` names the usual router in the help."""
    p.add_argument("--zenoh-connect", metavar="tcp/HOST:PORT", dest="zenoh_connect",
                   help=prefix + f"the Zenoh router to connect to{router} (default tcp/127.0.0.1:7447)")
    p.add_argument("--zenoh-listen", metavar="tcp/HOST:PORT", dest="zenoh_listen",
                   help=prefix + "be the router, listening here, instead of connecting to one")
    add_zenoh_config_option(p, prefix)


def zenoh_session_options(listen: str | None, connect: str | None, config: str | None, *,
                          lowlatency: bool = True) -> Any:
    """The :class:`aioadept.bus.zenoh.ZenohOptions` of those three options: the router itself with ``listen``, else
    a client of ``connect`` (default the local router). ValueError, one line, for both given or a bad value."""
    from aioadept.bus import zenoh as zb
    from aioadept.errors import BusError

    if listen and connect:
        raise ValueError("give --zenoh-listen (be the router) or --zenoh-connect (use one), not both")
    kw = {"lowlatency": lowlatency, "config_file": config or None}
    try:
        return (zb.ZenohOptions.router(listen, **kw) if listen
                else zb.ZenohOptions.client(connect or zb.DEFAULT_ROUTER, **kw))
    except BusError as exc:
        raise ValueError(str(exc)) from None


def add_node_transport_options(p: argparse.ArgumentParser) -> None:
    """A node's ``--transport`` and the Zenoh options that go with it."""
    add_transport_option(p)
    p.add_argument("--cell", help="--transport zenoh: the cell's name in the key expressions "
                                  "aioadept/CELL/NODE/TOPIC (default demo)")
    add_zenoh_session_options(p, "--transport zenoh: ")
    p.add_argument("--node", metavar="NAME",
                   help="--transport zenoh: this node's name in its liveliness token aioadept/CELL/NAME (default: "
                        "sim, vision or state; a cell of several robots names each, e.g. r1, cam1)")


def apply_node_transport(values: dict, node: str, streams: dict[str, tuple[str, str, str]]) -> None:
    """``--transport zenoh`` for node ``node`` (``sim``, ``vision``, ``state``): configure this process's Zenoh
    session (a client of ``zenoh_connect``, or the router itself with ``zenoh_listen``; multicast scouting and gossip
    off), turn every endpoint of ``values`` named in ``streams`` (key -> (its ZeroMQ default, owner node, topic))
    that is still at its ZeroMQ default into the cell's key ``zenoh:aioadept/CELL/OWNER/TOPIC``, and have the node
    declare its liveliness token when it prints READY. ValueError naming the option for a bad value."""
    if values.get("transport") != "zenoh":
        given = [o for o in _ZENOH_OPTIONS if values.get(o)]
        if given:
            raise ValueError(f"--{given[0].replace('_', '-')} needs --transport zenoh")
        return
    from aioadept.cell.bus import check_chunk
    from aioadept.bus import zenoh as zb
    from aioadept.errors import BusError

    cell = values.get("cell") or zb.DEFAULT_CELL
    try:
        check_chunk(cell, "--cell")
        zb.configure(zenoh_session_options(values.get("zenoh_listen"), values.get("zenoh_connect"),
                                           values.get("zenoh_config")))
        name = check_chunk(values.get("node") or node, "--node")
        zb.announce_as(cell, name)
    except BusError as exc:
        raise ValueError(str(exc)) from None
    for key, (zmq_default, owner, topic) in streams.items():
        if values.get(key) == zmq_default:
            values[key] = zb.endpoint_for(cell, owner, topic)


def apply_cell_bus(values: dict, bus: "BusSection", given: set[str], streams: dict[str, tuple[str, str]],
                   source: str) -> None:
    """A node started from a cell file (``aioadept sim|vision|state --config CELL.toml``): the file's ``[bus]``
    table applied to the node's options ``values`` (defaults < the file < the command line) as a starter applies it
    to the nodes it runs (:func:`aioadept.cell.bus.transport_argv` and
    :func:`~aioadept.cell.bus.with_transport`), so the node meets the demo's application on the same transport
    and keys. Call it before :func:`apply_node_transport`.

    ``given`` names the options the command line gave; each wins over the file: ``--transport`` over
    ``transport``, ``--cell`` over ``cell``, ``--zenoh-connect``/``--zenoh-listen`` over ``zenoh_router`` (a node
    connects to the router; it is never the router because of the file), an endpoint over the key the file's would
    become. On Zenoh every endpoint of ``streams`` (option -> (owner node, topic)) the command line did not give
    becomes the cell's key unless it is ``zenoh:`` or ``none`` (:func:`~aioadept.cell.bus.on_cell_key`).
    ValueError naming the option, or :class:`~aioadept.errors.ConfigError` naming the file and the key."""
    if "transport" not in given:
        values["transport"] = bus.transport
    if values.get("transport") != "zenoh":
        return
    from aioadept.cell.bus import check_chunk, on_cell_key
    from aioadept.errors import BusError

    if "cell" not in given:
        values["cell"] = bus.cell
    if not given & {"zenoh_connect", "zenoh_listen"}:
        if bus.zenoh_router.rpartition(":")[2] == "0":
            raise ConfigError(f"{source} [bus]: zenoh_router = {bus.zenoh_router!r}: port 0 is the free port a "
                              f"starter picks for the router it runs itself; a node started on its own needs the "
                              f"router's port (or --zenoh-connect)")
        values["zenoh_connect"] = bus.zenoh_router
    if "zenoh_config" not in given and bus.zenoh_config:
        values["zenoh_config"] = bus.zenoh_config
    try:
        check_chunk(values["cell"], "--cell")
    except BusError as exc:
        raise ValueError(str(exc)) from None
    for key, (owner, topic) in streams.items():
        if key not in given:
            values[key] = on_cell_key(values[key], values["cell"], owner, topic)


# ------------------------------------------------------------------------------------------------- listeners
# Who may reach a listener is who may use it: the one check every command that listens runs before it binds.


@dataclasses.dataclass(frozen=True)
class Listener:
    """One address a command listens on: the option that set it, the address as given (a bare host, ZeroMQ
    ``[@]tcp://HOST:PORT``, Zenoh ``tcp/HOST:PORT``, ``opc.tcp://HOST:PORT``), whether only authenticated peers get
    in (CURVE, Zenoh user/password or mutual TLS), and what an unauthenticated peer could do there."""

    option: str
    address: str
    authenticated: bool = False
    risk: str = "use it"


def add_insecure_option(p: argparse.ArgumentParser) -> None:
    """``--insecure``: accept listening beyond loopback without authentication (:func:`check_listeners`)."""
    p.add_argument("--insecure", action="store_true",
                   help="listen on an address beyond loopback although nothing authenticates who connects there: "
                        "refused without it (docs/security.md)")


def is_loopback(host: str) -> bool:
    """``localhost``, ``127.0.0.0/8`` or ``::1``. Any other name counts as beyond loopback (it is not resolved)."""
    import ipaddress

    host = host.strip().strip("[]")
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def listen_host(address: str) -> str | None:
    """The host part of a listener address (``*`` and ``0.0.0.0`` as given); None for ``ipc://``/``inproc://``
    (this machine's file system or process) and ``none``."""
    import re

    a = address.strip().lstrip("@>")
    if not a:
        return ""  # a bare empty host: every interface
    if a.lower() == "none" or a.startswith(("ipc://", "inproc://", "zenoh:")):
        return None
    m = re.match(r"^(?:[a-z.+]+://|(?:tcp|tls|udp|quic)/)?(\[[^\]]*\]|[^:/]*)", a)
    return m.group(1) if m else a


def zenoh_authenticates(config_file: str | None) -> bool:
    """Whether a Zenoh config file makes its listener admit only authenticated peers: ``transport/auth/usrpwd``
    with a user, or TLS with ``enable_mtls`` (client certificates)."""
    if not config_file:
        return False
    from aioadept.bus import zenoh as zb

    try:
        cfg = zb._zenoh().Config.from_file(config_file)
    except Exception:  # read again, and said in one line, when the session opens
        return False
    return (cfg.get_json("transport/auth/usrpwd/user") not in ("null", '""')
            or cfg.get_json("transport/link/tls/enable_mtls") == "true")


def check_listeners(prog: str, listeners: list[Listener], insecure: bool) -> None:
    """Before anything binds: ValueError (one line naming the option and address) for the first listener beyond
    loopback that authenticates nobody, unless ``insecure``; with ``insecure``, one warning line on stderr naming
    them all."""
    exposed = [x for x in listeners if not x.authenticated and (h := listen_host(x.address)) is not None
               and not is_loopback(h)]
    if not exposed:
        return
    if not insecure:
        x = exposed[0]
        raise ValueError(f"{x.option} {x.address!r}: {listen_host(x.address) or 'every interface'} is not loopback, "
                         f"and nothing authenticates who connects there: anyone who reaches it may {x.risk}; bind "
                         f"127.0.0.1, configure authentication (docs/security.md), or pass --insecure to accept it")
    print(f"{prog}: warning: --insecure: " + "; ".join(
        f"{x.option} {x.address} listens beyond loopback without authentication: anyone who reaches it may {x.risk}"
        for x in exposed), file=sys.stderr, flush=True)


def zenoh_listener(args: Any, risk: str) -> list[Listener]:
    """The ``--zenoh-listen`` of ``args`` (if given) as a :class:`Listener`, authenticated as its
    ``--zenoh-config`` says."""
    listen = getattr(args, "zenoh_listen", None) if not isinstance(args, dict) else args.get("zenoh_listen")
    config = getattr(args, "zenoh_config", None) if not isinstance(args, dict) else args.get("zenoh_config")
    if not listen:
        return []
    return [Listener("--zenoh-listen", listen, zenoh_authenticates(config), risk)]


def zmq_listener(option: str, endpoint: str | None, default_bind: bool, authenticated: bool,
                 risk: str) -> list[Listener]:
    """A ZeroMQ endpoint option as a :class:`Listener` if the socket binds (CZMQ ``@``, or its role's default)."""
    from aioadept.bus.endpoints import is_none, parse_endpoint
    from aioadept.errors import BusError

    if is_none(endpoint):
        return []
    try:
        ep = parse_endpoint(endpoint)  # type: ignore[arg-type]
    except BusError:
        return []  # its own check says what is wrong with it
    if ep.zenoh or not ep.binds(default_bind):
        return []
    return [Listener(option, endpoint, authenticated, risk)]  # type: ignore[arg-type]


def run_node(prog: str, main: Any) -> int:
    """``asyncio.run(main)`` for a node's command (``state``, ``bridge``, ``ros2``): what fails at run time (an
    endpoint that cannot be bound, a Zenoh session that cannot open, a controller that does not answer: OSError or
    AdeptError) is one line ``PROG: message`` on stderr and exit 1; anything else is a bug and keeps its traceback."""
    import asyncio

    from aioadept.errors import AdeptError

    try:
        return asyncio.run(main)
    except (OSError, AdeptError) as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 1
