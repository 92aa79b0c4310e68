"""Many robots and cameras in one cell: the cell file's ``[[robots]]`` and ``[[cameras]]`` arrays,
and one application that runs focus calibration on every robot at the same time over one bus.

Where it sits: :func:`multi_from_dict` turns a cell file with ``[[robots]]``/``[[cameras]]`` into one
:class:`~aioadept.apps.cell.CellConfig` per robot (the file's ``[robot]``/``[vision]``/``[focus]``/``[run]``/``[bus]``
tables are what every entry starts from; an entry's own keys override them), each checked by the same code as a
single-robot file. :func:`run_multi` is the coordinating application: it is the cell's Zenoh router (one session
for the whole process, scouting off, loopback), starts every robot's sim and camera node
(:func:`~aioadept.apps.cell.running_cell`), waits until every node is present, then starts every robot's focus run at
once (:func:`~aioadept.apps.cell.run_focus_once`) and waits for all of them. A robot whose run fails does not stop
the others (they are separate robots); a Ctrl-C stops every robot (the :class:`~aioadept.apps.interrupt.Interrupter`
guards each connection).

Keys on Zenoh: ``aioadept/<cell>/<robot>/state``, ``aioadept/<cell>/<camera>/request|response``, and each node's
liveliness token ``aioadept/<cell>/<robot or camera>``. Run folder: one folder per run with one sub-folder per robot,
each a complete single-robot run folder (``focus.json``, ``robot.csv``, ``logs/``, ...), and ``multi.json`` beside
them (docs/focus.md, "Many robots in one cell").
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import datetime as _dt
import json
import logging
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aioadept.apps.cell import CellConfig, RobotSection, RunOutcome, run_focus_once, running_cell
from aioadept.configfile import Range, check_ranges, check_section
from aioadept.errors import ConfigError
from aioadept.vision.options import VisionOptions

__all__ = ["MAX_ROBOTS", "Member", "MemberOutcome", "MultiCell", "is_multi", "multi_from_dict", "prepared",
           "run_multi"]

log = logging.getLogger("aioadept.multicell")

MAX_ROBOTS = 16
"""Robots one cell file may hold (and as many cameras): each brings two processes to this machine."""
ROBOTS = Range(1, MAX_ROBOTS, integer=True)
_NAME = re.compile(r"^[A-Za-z0-9_.\-]{1,32}$")
_RESERVED = ("app", "sim", "vision")
"""Node names the single-robot cell and the application already use in the key expressions."""
PRESENCE_TIMEOUT_S = 10.0
"""How long the application waits for every node's liveliness token after the nodes printed READY."""


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
    from aioadept.configfile import load_toml

    return multi_from_dict(load_toml(path), source=str(path))


# ------------------------------------------------------------------------------------------------- running it


def prepared(multi: MultiCell) -> list[Member]:
    """The members with what one cell's transport decides for all: on Zenoh one router (a free loopback port for
    ``:0``, picked once), every stream on its owner's key (``aioadept/<cell>/<robot>/state``,
    ``aioadept/<cell>/<camera>/request``) and every node started with ``--node`` so its liveliness token names
    it. Nothing changes on ZeroMQ."""
    from aioadept.ports import free_port

    bus = multi.base.bus
    if not bus.zenoh:
        return [dataclasses.replace(m) for m in multi.members]
    router = bus.zenoh_router
    if bus.start_router and router.endswith(":0"):
        host = router[len("tcp/"):].rpartition(":")[0]
        router = f"tcp/{host}:{free_port(host)}"
    from aioadept.bus.endpoints import is_none
    from aioadept.bus.zenoh import endpoint_for, is_zenoh

    out = []
    for m in multi.members:
        cfg = m.cfg
        cfg = dataclasses.replace(cfg, bus=dataclasses.replace(cfg.bus, zenoh_router=router,
                                                               start_router=bus.start_router),
                                  robot=dataclasses.replace(cfg.robot), vision=dataclasses.replace(cfg.vision))
        for section, name, owner, topic in ((cfg.robot, "state_endpoint", m.robot, "state"),
                                            (cfg.vision, "request_endpoint", m.camera, "request"),
                                            (cfg.vision, "response_endpoint", m.camera, "response")):
            value = getattr(section, name)
            if not is_none(value) and not is_zenoh(value):
                setattr(section, name, endpoint_for(cfg.bus.cell, owner, topic))
        cfg.robot.sim_args = [*cfg.robot.sim_args, "--node", m.robot]
        cfg.vision.vision_args = [*cfg.vision.vision_args, "--node", m.camera]
        out.append(Member(m.robot, m.camera, cfg))
    return out


@dataclass(frozen=True, slots=True)
class MemberOutcome:
    robot: str
    camera: str
    run_dir: Path
    outcome: RunOutcome | None
    error: str | None
    wall_s: float | None = None
    """From the common start to this robot's result (None when it never started)."""


class _Gate:
    """Every member's nodes up before any robot moves: "at the same time" means after the slowest node started."""

    def __init__(self, n: int) -> None:
        self.waiting = n
        self.opened = asyncio.Event()
        self.t0: float | None = None

    def leave(self) -> None:
        self.waiting -= 1
        if self.waiting <= 0 and not self.opened.is_set():
            self.t0 = time.monotonic()
            self.opened.set()


async def _one(m: Member, run_dir: Path, gate: _Gate, ready: asyncio.Future[None] | None,
               interrupter: Any) -> MemberOutcome:
    from aioadept.apps.demo import _with_frames_checked

    sub = run_dir / m.robot
    sub.mkdir(parents=True, exist_ok=True)
    entered = False
    try:
        async with running_cell(m.cfg, sub / "logs", own_session=False) as cell:
            entered = True
            gate.leave()
            await gate.opened.wait()
            if ready is not None:
                await ready  # every node's liveliness token seen (Zenoh)
            outcome = await cell.run(run_focus_once(cell.cfg, sub, interrupter=interrupter))
            wall_s = time.monotonic() - (gate.t0 or time.monotonic())
    except asyncio.CancelledError:
        raise
    except Exception as exc:  # this robot failed; the others go on (separate robots, separate runs)
        if not entered:
            gate.leave()
        log.error("robot %s: %s: %s", m.robot, type(exc).__name__, exc)
        return MemberOutcome(m.robot, m.camera, sub, None, f"{type(exc).__name__}: {exc}")
    return MemberOutcome(m.robot, m.camera, sub, _with_frames_checked(m.cfg, sub, outcome), None, wall_s)


async def _all_present(members: list[Member], cell: str, watcher: Any) -> None:
    names = {n for m in members for n in (m.robot if m.cfg.robot.start_sim else None,
                                            m.camera if m.cfg.vision.start else None) if n}
    for name in sorted(names):
        await watcher.wait_for(name, True, timeout_s=PRESENCE_TIMEOUT_S)


async def run_multi(multi: MultiCell, run_dir: Path, *, interrupter: Any = None,
                    presence_log: list[dict[str, Any]] | None = None) -> list[MemberOutcome]:
    """Start every member's nodes, run focus calibration on all robots at once, stop every node; one
    :class:`MemberOutcome` per robot, in the file's order, and ``multi.json`` in ``run_dir``. ``presence_log``
    (Zenoh) receives each node appearing and vanishing as the application saw it (``{"node", "alive", "t_s"}``,
    seconds since it began to watch); ``multi.json`` keeps it as ``presence``."""
    from aioadept.apps.cellbus import zenoh_session

    members = prepared(multi)
    base = members[0].cfg
    gate = _Gate(len(members))
    if presence_log is None:
        presence_log = []
    with zenoh_session(base):  # the cell's router (or a client of it), for every member's streams
        async with contextlib.AsyncExitStack() as stack:
            ready: asyncio.Future[None] | None = None
            if base.bus.zenoh:
                from aioadept.bus.presence import NodeWatcher

                watcher = await stack.enter_async_context(NodeWatcher(base.bus.cell))
                t_watch = time.monotonic()
                stack.push_async_callback(_cancelled, asyncio.ensure_future(
                    _log_presence(watcher, presence_log, t_watch)))
                ready = asyncio.ensure_future(_all_present(members, base.bus.cell, watcher))
                stack.push_async_callback(_cancelled, ready)
            tasks = [_one(m, run_dir, gate, ready, interrupter) for m in members]
            results = await asyncio.gather(*tasks)
    _write_summary(run_dir, base, results, presence_log)
    return list(results)


async def _cancelled(fut: asyncio.Future[Any]) -> None:
    fut.cancel()
    with contextlib.suppress(asyncio.CancelledError, Exception):
        await fut


async def _log_presence(watcher: Any, out: list[dict[str, Any]], t0: float) -> None:
    async for ev in watcher:
        out.append({"node": ev.node, "alive": ev.alive, "t_s": round(time.monotonic() - t0, 4)})


def member_dict(r: MemberOutcome, cfg: CellConfig | None = None) -> dict[str, Any]:
    res = r.outcome.result if r.outcome is not None else None
    error = r.error or (r.outcome.error if r.outcome is not None else None)
    out: dict[str, Any] = {"robot": r.robot, "camera": r.camera, "run_dir": r.run_dir.name, "error": error,
                           "wall_s": r.wall_s}
    if cfg is not None:
        out["focus_offset_mm"] = cfg.vision.focus_offset_mm
    if res is not None:
        out.update(peak_offset_mm=res.peak_offset_mm, steps=res.steps, search_s=res.search_s, mode=res.mode,
                   cycle_s=(res.search_s / res.steps) if res.search_s is not None and res.steps else None)
    return out


def _write_summary(run_dir: Path, base: CellConfig, results: list[MemberOutcome],
                   presence: list[dict[str, Any]]) -> None:
    from aioadept.capture import write_atomic

    data = {"app": "focus-multi", "written_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(),
            "transport": base.bus.transport, "cell": base.bus.cell,
            "zenoh_router": base.bus.zenoh_router if base.bus.zenoh else None,
            "robots": [member_dict(r) for r in results],
            "presence": presence if base.bus.zenoh else None}
    try:
        write_atomic(run_dir / "multi.json", json.dumps(data, indent=2))
    except OSError as exc:
        log.error("multi.json not written in %s: %s", run_dir, exc.strerror or exc)


def new_multi_run_dir(multi: MultiCell) -> Path:
    """``OUT/<stamp>-<name or multi-N>``: one folder for the run, a sub-folder per robot."""
    cfg = multi.base
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S-%f")[:-3]
    d = Path(cfg.run.out_dir) / f"{stamp}-{cfg.run.name or f'multi-{len(multi.members)}'}"
    d.mkdir(parents=True, exist_ok=False)
    return d
