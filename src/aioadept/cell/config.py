"""The cell file's schema: one table per section (``[robot]``, ``[vision]``, ``[focus]``, ``[run]``,
``[pickplace]``, ``[world]``, ``[bus]``, ``[calibration]``), read into a :class:`CellConfig` whose errors name the
file, the table and the key. ``aioadept demo`` and ``aioadept focus`` both run a :class:`CellConfig`; a TOML file
can hold one (see ``examples/cell.toml``), so each node can move to another machine by editing an address.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aioadept.apps.focus import FocusParams
from aioadept.apps.pickplace import PickPlaceParams
from aioadept.cell.bus import BusSection
from aioadept.cell.schema import Range, ranged
from aioadept.commands import SPEED_MAX, SPEED_MIN
from aioadept.defaults import ROBOT_HOST, ROBOT_PORT, STATE_ENDPOINT
from aioadept.vision.options import VisionOptions
from aioadept.world import WorldConfig


@dataclass(slots=True)
class RobotSection:
    host: str = ROBOT_HOST
    port: int = ranged(ROBOT_PORT, Range(0, 0xFFFF, integer=True))
    """0 with ``start_sim``: pick a free port."""
    stop_port: int = 0
    """The server's stop port (serves only stop/here/hello: docs/protocol.md 4.2.1), which the client uses by itself
    when its connection cannot deliver a stop. 0: ``port`` + 1 (1235 beside 1234), or a free one with ``start_sim``
    and ``port = 0``."""
    start_sim: bool = True
    """Start ``aioadept sim`` on this machine (else connect to a running server, e.g. a real controller)."""
    time_scale: float = ranged(1.0, Range(0.0, lo_open=True))
    """Sim motion speed-up (1 = real time)."""
    monitor_speed: int = ranged(100, Range(SPEED_MIN, SPEED_MAX, integer=True, unit="%"))
    state_endpoint: str = STATE_ENDPOINT
    """Where the sim publishes the robot state (the virtual camera subscribes). Port 0: pick a free one."""
    connect_timeout_s: float = ranged(5.0, Range(0.0, lo_open=True, unit="s"))
    ack_timeout_s: float = ranged(30.0, Range(0.0, lo_open=True, unit="s"))
    hello_timeout_s: float = ranged(2.0, Range(0.0, unit="s"))
    """After connecting, send ``hello`` and give up this soon if nothing like a RobotServer answers (a wrong port).
    0: no check (the original V+ AdeptServer, whose task halts on an unknown skill)."""
    model: str = "viper-s850"
    """The arm the sim simulates (``aioadept sim --robot-model``; docs/sim.md, Robot models)."""
    sim_args: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        from aioadept.robots import model

        model(self.model)  # ValueError naming the known models


@dataclass(slots=True)
class VisionSection(VisionOptions):
    """The cell file's ``[vision]`` table: every option of the vision node (:class:`VisionOptions`, the one schema
    ``aioadept vision --config`` reads too), and what only a starter needs."""

    start: bool = True
    """Start ``aioadept vision`` on this machine."""
    vision_args: list[str] = field(default_factory=list)
    """Further command-line arguments for the node."""


@dataclass(slots=True)
class RunSection:
    out_dir: str = "runs"
    analyze: bool = True
    name: str = ""
    record: bool = True
    """Write ``run.rrd`` (Rerun) and ``run.mcap`` into every run folder when the [viewer] / [mcap] extras are
    installed (docs/record.md)."""
    view_url: str = ""
    """gRPC address of a live viewer each run streams to (set by ``--view``); empty: none."""


@dataclass(slots=True)
class CellConfig:
    robot: RobotSection = field(default_factory=RobotSection)
    vision: VisionSection = field(default_factory=VisionSection)
    focus: FocusParams = field(default_factory=FocusParams)
    run: RunSection = field(default_factory=RunSection)
    pickplace: PickPlaceParams = field(default_factory=PickPlaceParams)
    """The ``[pickplace]`` table (docs/pickplace.md)."""
    world: WorldConfig | None = None
    """The simulated world (``[world]``: table, parts, feeder, pallet, camera; aioadept.cell.world), or None."""
    bus: BusSection = field(default_factory=BusSection)
    calibration: Any = None
    """The camera-to-robot calibration (``[calibration]``: :class:`aioadept.vision.calibration.CameraCalibration`,
    written by ``aioadept calibrate``), or None."""

    @classmethod
    def from_toml(cls, path: str | Path) -> CellConfig:
        from aioadept.cell.schema import load_toml

        return cls.from_dict(load_toml(path), source=str(path))

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "config") -> CellConfig:
        from aioadept.errors import ConfigError

        known = {"robot": RobotSection, "vision": VisionSection, "focus": FocusParams, "run": RunSection,
                 "world": WorldConfig, "bus": BusSection, "pickplace": PickPlaceParams}
        unknown = set(data) - set(known) - {"calibration"}
        if unknown & {"robots", "cameras"}:
            raise ConfigError(f"{source}: [[robots]]/[[cameras]] describe a cell of several robots, which only "
                              f"`aioadept demo --config FILE` runs (docs/focus.md, \"Many robots in one cell\")")
        if unknown:
            raise ConfigError(f"{source}: unknown section(s) {', '.join(sorted(unknown))}; expected "
                              f"{', '.join([*known, 'calibration'])}")
        parts: dict[str, Any] = {}
        if "calibration" in data:
            from aioadept.vision.calibration import CameraCalibration

            parts["calibration"] = CameraCalibration.from_table(data["calibration"], f"{source} [calibration]")
        for name, typ in known.items():
            if name in data or typ is not WorldConfig:
                parts[name] = _section(typ, data.get(name, {}), f"{source} [{name}]", source)
        cfg = cls(**parts)
        _check_cell(cfg, source)
        return cfg

    def to_dict(self) -> dict[str, Any]:
        """The cell as a run records it (``run.json``'s ``cell``): the values this run used. ``[vision]
        state_endpoint`` is left out: a node the cell starts follows the robot's (``robot.state_endpoint``, given
        on its command line), and one started elsewhere reads its own."""
        out = dataclasses.asdict(self)
        out["vision"].pop("state_endpoint", None)
        return out


def _section(typ: type, table: Any, where: str, source: str) -> Any:
    """One section of the cell file, its unknown keys, wrong types and values out of range as one line naming
    file, key and what was expected (ConfigError)."""
    from aioadept.cell.schema import check_ranges, check_section
    from aioadept.errors import ConfigError

    if typ is WorldConfig:
        from aioadept.cell.world import world_from_table

        return world_from_table(table, where)
    if typ is VisionSection:
        return VisionSection.from_table(table, where)
    try:
        part = typ(**check_section(typ, table, where))  # FocusParams checks its ranges
        check_ranges(part)
        if typ is BusSection:
            if part.zenoh_config and Path(source).is_file():  # relative to the cell file, as its other files
                part.zenoh_config = str(Path(source).parent / part.zenoh_config)
            part.check(where)
    except ConfigError:
        raise
    except ValueError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    return part


def _check_cell(cfg: CellConfig, source: str) -> None:
    """What one section alone cannot check: the world the camera needs, the locate graph's calibration, the
    robot's state stream."""
    from aioadept.errors import ConfigError

    v = cfg.vision
    if "world" in v.sources() and not v.world and (cfg.world is None or cfg.world.camera is None):
        raise ConfigError(f'{source} [vision]: source = "world" needs a [world] table with [world.camera] (or '
                          f'world = FILE)')
    if cfg.calibration is not None and v.graph == "locate" and not v.calibration and Path(source).is_file():
        v.calibration = source  # the node a starter runs reads this file's [calibration] (vision_argv)
    if v.graph == "locate" and not v.calibration:
        raise ConfigError(f'{source} [vision]: graph = "locate" needs a [calibration] table (aioadept calibrate '
                          f'writes one) or calibration = FILE')
    if not v.exposure_ms > 0:  # the node takes 0 (a camera's own minimum); a cell's camera must expose
        raise ConfigError(f"{source} [vision]: exposure_ms = {v.exposure_ms!r}: expected a finite number of "
                          f"ms > 0")
    from aioadept.bus.endpoints import is_none, parse_endpoint
    from aioadept.errors import BusError

    try:
        if not is_none(cfg.robot.state_endpoint):  # "none": the sim publishes no state stream
            parse_endpoint(cfg.robot.state_endpoint)
    except BusError as exc:
        raise ConfigError(f"{source}: robot.state_endpoint: {exc}") from None
