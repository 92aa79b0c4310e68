"""Many robots and cameras in one cell: one application that runs focus calibration on every robot at the same
time over one bus.

Where it sits: :func:`aioadept.cell.multi.multi_from_dict` turns a cell file with ``[[robots]]``/``[[cameras]]`` into
one :class:`~aioadept.cell.config.CellConfig` per robot. :func:`run_multi` is the coordinating application: it is the
cell's Zenoh router (one session for the whole process, scouting off, loopback), starts every robot's sim and camera
node (:func:`~aioadept.apps.cell.running_cell`), waits until every node is present, then starts every robot's focus run
at once (:func:`~aioadept.apps.cell.run_focus_once`) and waits for all of them. A robot whose run fails does not stop
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
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aioadept.apps.cell import RunOutcome, run_focus_once, running_cell
from aioadept.cell.config import CellConfig
from aioadept.cell.multi import Member, MultiCell

__all__ = ["MemberOutcome", "prepared", "run_multi"]

log = logging.getLogger("aioadept.multicell")

PRESENCE_TIMEOUT_S = 10.0
"""How long the application waits for every node's liveliness token after the nodes printed READY."""


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
    from aioadept.cell.bus import zenoh_session

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
    from aioadept.runs.capture import write_atomic

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
