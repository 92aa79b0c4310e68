"""The cell file's ``[[robots]]`` and ``[[cameras]]`` arrays: a cell of several robots and cameras, read into one
:class:`~aioadept.cell.config.CellConfig` per robot (the file's ``[robot]``/``[vision]``/``[focus]``/``[run]``/``[bus]``
tables are what every entry starts from; an entry's own keys override them), each checked by the same code as a
single-robot file. :mod:`aioadept.apps.multicell` runs such a cell (docs/focus.md, "Many robots in one cell").
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aioadept.cell.config import CellConfig, RobotSection
from aioadept.cell.schema import Range, check_ranges, check_section
from aioadept.errors import ConfigError
from aioadept.vision.options import VisionOptions

MAX_ROBOTS = 16
"""Robots one cell file may hold (and as many cameras): each brings two processes to this machine."""
ROBOTS = Range(1, MAX_ROBOTS, integer=True)
_NAME = re.compile(r"^[A-Za-z0-9_.\-]{1,32}$")
_RESERVED = ("app", "sim", "vision")
"""Node names the single-robot cell and the application already use in the key expressions."""


def is_multi(data: dict[str, Any]) -> bool:
    """Whether a cell file's tables describe several robots (``[[robots]]`` or ``[[cameras]]``)."""
    return "robots" in data or "cameras" in data


@dataclass(slots=True)
class Member:
    """One robot of the cell with the camera that looks at its target, as a whole single-robot cell."""

    robot: str
    camera: str
    cfg: CellConfig


@dataclass(slots=True)
class MultiCell:
    members: list[Member]
    source: str = "config"

    @property
    def base(self) -> CellConfig:
        return self.members[0].cfg


def _entries(data: dict[str, Any], key: str, source: str) -> list[dict[str, Any]]:
    value = data.get(key)
    if value is None:
        raise ConfigError(f"{source}: [[{key}]] missing: a cell of several robots needs [[robots]] and [[cameras]] "
                          f"(examples/multi-cell.toml)")
    if not isinstance(value, list) or not all(isinstance(e, dict) for e in value):
        raise ConfigError(f"{source}: {key}: expected an array of tables ([[{key}]]), got {type(value).__name__}")
    if not ROBOTS.contains(len(value)):
        raise ConfigError(f"{source}: {len(value)} [[{key}]]: expected {ROBOTS.words}")
    return value


def _name(entry: dict[str, Any], where: str, taken: dict[str, str]) -> str:
    name = entry.get("name")
    if not isinstance(name, str) or not _NAME.match(name):
        raise ConfigError(f"{where}: name = {name!r}: expected 1 to 32 letters, digits, '_', '.' or '-' (one Zenoh "
                          f"key chunk), e.g. \"r1\"")
    if name in _RESERVED:
        raise ConfigError(f"{where}: name = {name!r}: reserved ({', '.join(_RESERVED)}); choose another")
    if name in taken:
        raise ConfigError(f"{where}: name = {name!r}: already used by {taken[name]}")
    return name


def multi_from_dict(data: dict[str, Any], *, source: str = "config") -> MultiCell:
    """The cell of a file with ``[[robots]]`` and ``[[cameras]]``; :class:`ConfigError` (one line naming the file,
    the entry and the key) for anything wrong: an unknown key, a value of the wrong type or out of range, a name
    used twice, a camera on a robot that does not exist, a robot without exactly one camera, two robots on one
    address."""
    shared = {k: v for k, v in data.items() if k not in ("robots", "cameras")}
    CellConfig.from_dict(shared, source=source)  # the shared tables alone: checked and named as in a single cell
    robots = _entries(data, "robots", source)
    cameras = _entries(data, "cameras", source)
    taken: dict[str, str] = {}
    robot_tables: dict[str, dict[str, Any]] = {}
    for i, entry in enumerate(robots, 1):
        where = f"{source} [[robots]] #{i}"
        name = _name(entry, where, taken)
        where = f'{source} [[robots]] name = "{name}"'
        table = {k: v for k, v in entry.items() if k != "name"}
        try:  # the entry's own keys, named as the entry's, before they are merged
            check_ranges(RobotSection(**check_section(RobotSection, table, where)))
        except ConfigError:
            raise
        except ValueError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        taken[name] = f'[[robots]] #{i}'
        robot_tables[name] = table
    on_robot: dict[str, tuple[str, dict[str, Any]]] = {}
    for i, entry in enumerate(cameras, 1):
        where = f"{source} [[cameras]] #{i}"
        name = _name(entry, where, taken)
        where = f'{source} [[cameras]] name = "{name}"'
        robot = entry.get("robot")
        if robot not in robot_tables:
            raise ConfigError(f"{where}: robot = {robot!r}: expected the name of one of the [[robots]] "
                              f"({', '.join(robot_tables)})")
        if robot in on_robot:
            raise ConfigError(f"{where}: robot = {robot!r}: that robot already has camera {on_robot[robot][0]!r}; "
                              f"focus calibration takes one camera per robot")
        table = {k: v for k, v in entry.items() if k not in ("name", "robot")}
        VisionOptions.from_table({**{k: v for k, v in shared.get("vision", {}).items()
                                     if k not in ("start", "vision_args")}, **{k: v for k, v in table.items()
                                                                             if k not in ("start", "vision_args")}},
                                 where)
        taken[name] = f'[[cameras]] #{i}'
        on_robot[robot] = (name, table)
    missing = [r for r in robot_tables if r not in on_robot]
    if missing:
        raise ConfigError(f"{source}: robot {missing[0]!r} has no camera: add [[cameras]] with robot = "
                          f"{missing[0]!r} (focus calibration takes one camera per robot)")
    members = []
    for robot, table in robot_tables.items():
        camera, cam_table = on_robot[robot]
        one = {**shared, "robot": {**_free_addresses("robot", shared, table), **shared.get("robot", {}), **table},
               "vision": {**_free_addresses("vision", shared, cam_table), **shared.get("vision", {}), **cam_table}}
        cfg = CellConfig.from_dict(one, source=f'{source} (robot "{robot}", camera "{camera}")')
        members.append(Member(robot, camera, cfg))
    _check_distinct(members, source)
    return MultiCell(members, source)


def _free_addresses(table: str, shared: dict[str, Any], entry: dict[str, Any]) -> dict[str, Any]:
    """The addresses a started node gets when neither the entry nor the shared table writes them: free ports (port 0),
    as ``aioadept demo`` without a file; the single-robot defaults (1234, 5555, ...) would make every robot collide."""
    keys = {"robot": {"port": 0, "state_endpoint": "tcp://127.0.0.1:0"},
            "vision": {"request_endpoint": "tcp://127.0.0.1:0", "response_endpoint": "tcp://127.0.0.1:0"}}[table]
    written = {**shared.get(table, {}), **entry}
    return {k: v for k, v in keys.items() if k not in written}


def _check_distinct(members: list[Member], source: str) -> None:
    """Two robots on one fixed address would meet the same server: one line naming both."""
    seen: dict[tuple[str, Any], str] = {}
    for m in members:
        fixed = [("robot port", f"{m.cfg.robot.host}:{m.cfg.robot.port}"),
                 ("state_endpoint", m.cfg.robot.state_endpoint),
                 ("request_endpoint", m.cfg.vision.request_endpoint),
                 ("response_endpoint", m.cfg.vision.response_endpoint)]
        for item in fixed:
            if item[1].endswith(":0") or item[1] == "none":  # a free port each, or no stream
                continue
            if item in seen:
                raise ConfigError(f"{source}: {item[0]} {item[1]!r} of robot {m.robot!r} is also used by robot "
                                  f"{seen[item]!r}: each robot and camera needs addresses of its own (or port 0: "
                                  f"a free one)")
            seen[item] = m.robot


def load_multi(path: str | Path) -> MultiCell:
    from aioadept.cell.schema import load_toml

    return multi_from_dict(load_toml(path), source=str(path))
