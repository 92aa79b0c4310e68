"""``aioadept opcua --config CELL``: the OPC UA server of a cell file, one MotionDevice per robot.

The robots are the file's ``[robot]`` (one) or its ``[[robots]]`` entries (each over the shared ``[robot]``, as
``aioadept demo`` reads them, :mod:`aioadept.apps.multicell`): each robot's server address (``host``, ``port``), its
state stream (``state_endpoint``) and its model (``model``: the axes, which of them slide, the MotionDeviceCategory).
The ``[opcua]`` table holds the server's own settings and, in ``[opcua.devices.NAME]``, what the cell knows of each
robot that no controller says (serial numbers, the controller's model). Every mistake is a :class:`ConfigError`: one
line naming the file, the table and the key. docs/opcua.md, "A cell file".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aioadept.cell.schema import ConfigError, check_ranges, check_section, load_toml
from aioadept.opcua.mapping import STALE_AFTER_S, Identity, MotionDeviceCategory, identity_of_model
from aioadept.opcua.security import check_modes

__all__ = ["DEFAULT_ENDPOINT", "CellPlan", "DeviceSection", "OpcuaSection", "RobotPlan", "plan_from_dict",
           "load_plan"]

DEFAULT_ENDPOINT = "opc.tcp://127.0.0.1:4840"
DEFAULT_NAME = "Robot1"


@dataclass(slots=True)
class DeviceSection:
    """``[opcua.devices.NAME]``: one robot's identity as the cell knows it (empty: not known, the variable is Bad).
    ``model`` and ``category`` default to the robot model's (``[robot] model``) when the cell names one."""

    manufacturer: str = Identity().manufacturer
    model: str = ""
    serial_number: str = ""
    product_code: str = ""
    category: str = ""
    controller_model: str = ""
    controller_serial_number: str = ""


@dataclass(slots=True)
class OpcuaSection:
    """The ``[opcua]`` table (the command line's options of the same names override it)."""

    endpoint: str = DEFAULT_ENDPOINT
    allow_commands: bool = False
    users: str = ""
    """The users file (relative to the cell file), needed with ``allow_commands``."""
    stale_after_s: float = STALE_AFTER_S
    security: list[str] = field(default_factory=lambda: ["none"])
    """The modes offered (aioadept.opcua.security.MODES)."""
    certificate: str = ""
    """The server's certificate (relative to the cell file), with ``private_key``; none: one made at first start."""
    private_key: str = ""
    trust: str = ""
    """The trust list: a folder of client application certificates (relative to the cell file); none: any client."""
    user_certificates: str = ""
    """A folder of user certificates that may command (relative to the cell file), with ``allow_commands``."""
    name: str = DEFAULT_NAME
    """The MotionDevice's browse name of a cell with one ``[robot]`` (``[[robots]]`` entries have their own)."""
    devices: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class RobotPlan:
    """One robot the server shows: its MotionDevice's identity, and where its server and state stream are."""

    host: str
    port: int
    state_endpoint: str
    identity: Identity

    @property
    def name(self) -> str:
        return self.identity.name


@dataclass(frozen=True, slots=True)
class CellPlan:
    opcua: OpcuaSection
    robots: tuple[RobotPlan, ...]
    many: bool
    """Whether the file has ``[[robots]]`` (then the robots' options on the command line are refused)."""


def identity_for(name: str, model: str | None, device: dict[str, Any], where: str) -> Identity:
    """The identity of robot ``name`` of ``model`` (None: not said, the Viper s850's axes but no Model or category)
    with the ``device`` table's keys (checked, named by ``where``)."""
    d = DeviceSection(**check_section(DeviceSection, device, where))
    keys = {k: getattr(d, k) for k in ("manufacturer", "serial_number", "product_code", "controller_model",
                                       "controller_serial_number")}
    if d.category:
        try:
            keys["category"] = MotionDeviceCategory[d.category]
        except KeyError:
            raise ConfigError(f"{where}: category = {d.category!r}: expected one of "
                              f"{', '.join(c.name for c in MotionDeviceCategory)}") from None
    elif model is None:
        keys["category"] = None
    if d.model or model is None:
        keys["model"] = d.model
    return identity_of_model(model or "viper-s850", name=name, **keys)


def _robot(table: dict[str, Any], where: str) -> Any:
    from aioadept.cell.config import RobotSection

    try:
        robot = RobotSection(**check_section(RobotSection, table, where))
        check_ranges(robot)
    except ConfigError:
        raise
    except ValueError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    if robot.port == 0 or robot.state_endpoint.rstrip("/").endswith(":0"):
        raise ConfigError(f"{where}: port 0 picks a free port for a sim a starter runs; aioadept opcua follows a "
                          f"running robot: give its port and its state_endpoint's")
    return robot


def plan_from_dict(data: dict[str, Any], *, source: str = "config") -> CellPlan:
    """The server of the cell file ``data`` (``source`` names it in messages). :class:`ConfigError` for an unknown
    key, a value of the wrong type, a name used twice, a device table of no robot, two robots on one address, a port
    0, or a cell whose robot.state goes over Zenoh (this server follows ZeroMQ only)."""
    from aioadept.cell.config import CellConfig
    from aioadept.cell.multi import _entries, _name, is_multi

    rest = {k: v for k, v in data.items() if k != "opcua"}
    section = OpcuaSection(**check_section(OpcuaSection, data.get("opcua", {}), f"{source} [opcua]"))
    if not section.stale_after_s > 0:
        raise ConfigError(f"{source} [opcua]: stale_after_s = {section.stale_after_s!r}: expected seconds > 0")
    try:
        check_modes(section.security, f"{source} [opcua]: security =")
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    for key in ("users", "certificate", "private_key", "trust", "user_certificates"):
        if getattr(section, key) and Path(source).is_file():  # relative to the cell file, as its other files
            setattr(section, key, str(Path(source).parent / getattr(section, key)))
    many = is_multi(rest)
    shared = {k: v for k, v in rest.items() if k not in ("robots", "cameras")}
    cell = CellConfig.from_dict(shared, source=source)  # the shared tables checked as every node checks them
    if cell.bus.zenoh:
        raise ConfigError(f"{source} [bus]: transport = \"zenoh\": aioadept opcua follows robot.state over ZeroMQ "
                          f"only")
    tables: list[tuple[str, dict[str, Any], str]] = []
    if many:
        taken: dict[str, str] = {}
        for i, entry in enumerate(_entries(rest, "robots", source), 1):
            name = _name(entry, f"{source} [[robots]] #{i}", taken)
            taken[name] = f"[[robots]] #{i}"
            table = {**shared.get("robot", {}), **{k: v for k, v in entry.items() if k != "name"}}
            tables.append((name, table, f'{source} [[robots]] name = "{name}"'))
    else:
        tables.append((section.name, shared.get("robot", {}), f"{source} [robot]"))
    devices = section.devices
    unknown = sorted(set(devices) - {name for name, _, _ in tables})
    if unknown:
        raise ConfigError(f"{source} [opcua.devices.{unknown[0]}]: no robot is called {unknown[0]!r} (robots: "
                          f"{', '.join(name for name, _, _ in tables)})")
    robots: list[RobotPlan] = []
    seen: dict[str, str] = {}
    for name, table, where in tables:
        robot = _robot(table, where)
        for what in (f"{robot.host}:{robot.port}", robot.state_endpoint):
            if what in seen:
                raise ConfigError(f"{where}: {what} is also robot {seen[what]!r}'s: each robot needs its own server "
                                  f"and state stream")
            seen[what] = name
        identity = identity_for(name, robot.model if "model" in table else None, devices.get(name, {}),
                                f"{source} [opcua.devices.{name}]")
        robots.append(RobotPlan(robot.host, robot.port, robot.state_endpoint, identity))
    return CellPlan(section, tuple(robots), many)


def load_plan(path: str | Path) -> CellPlan:
    return plan_from_dict(load_toml(path), source=str(path))
