"""One ``aioadept pickplace`` run against a cell: connect to the robot server and the vision node, run
:func:`aioadept.apps.pickplace.pickplace`, and write the run folder (the timing logs, run.rrd and run.mcap as the
focus app's, ``pickplace.json``, ``summary.json``, ``gantt.png``, ``cycle_hist.png``).

``summary.json``: ``parts_placed``, ``parts_failed``, ``place_error_mm`` / ``place_error_deg`` (per placed part,
from the world's truth on the sim's ``world.state`` stream against its slot; empty without a world stream),
``cycle_ms`` and ``floor_ms`` (per part: the commanded motions' durations and the hand waits on the server's clock,
plus the locate request's time), ``error``.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as _dt
import json
import logging
import math
import statistics
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from aioadept.apps.cell import _guarded, stop_port_of
from aioadept.cell.config import CellConfig
from aioadept.runs.folder import abandon_run, run_error
from aioadept.apps.pickplace import BusLocator, PickPlaceParams, PickPlaceResult, pickplace
from aioadept.errors import PickPlaceError

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class PickPlaceOutcome:
    run_dir: Path
    summary: dict[str, Any]
    error: str | None


class WorldWatch:
    """The latest ``WorldState`` of the sim's state stream (the truth place errors are measured against)."""

    def __init__(self, endpoint: str) -> None:
        self.endpoint = endpoint
        self.latest: Any = None
        self._new = asyncio.Event()
        self._sub: Any = None
        self._task: asyncio.Task | None = None

    async def __aenter__(self) -> WorldWatch:
        from aioadept.bus import Subscriber
        from aioadept.bus.messages import WORLD_STATE_TOPIC

        self._sub = await Subscriber(self.endpoint, topics=[WORLD_STATE_TOPIC]).__aenter__()
        self._task = asyncio.create_task(self._follow())
        return self

    async def __aexit__(self, *exc: Any) -> None:
        assert self._task is not None
        self._task.cancel()
        await asyncio.gather(self._task, return_exceptions=True)
        await self._sub.__aexit__(*exc)

    async def _follow(self) -> None:
        from aioadept.bus.messages import WorldState

        while True:
            _topic, payload = await self._sub.recv()
            self.latest = WorldState.from_bytes(payload)
            self._new.set()

    async def fresh(self, timeout_s: float = 2.0) -> Any:
        """A state published after this call (None if none comes within ``timeout_s``)."""
        self._new.clear()
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(timeout_s):
                await self._new.wait()
                return self.latest
        return None


def place_errors(ws: Any, result: PickPlaceResult, pallet: Any) -> tuple[list[float], list[float], int]:
    """Per placed part: distance (mm) and heading difference (deg) of the part nearest its slot; and the parts
    marked dropped."""
    err_mm, err_deg = [], []
    for c in result.cycles:
        if not c.placed:
            continue
        x, y, h = pallet.slot_xy(c.slot)
        near = min(ws.parts, key=lambda st: math.hypot(st.pose.x - x, st.pose.y - y))
        err_mm.append(round(math.hypot(near.pose.x - x, near.pose.y - y), 4))
        err_deg.append(round(abs((near.heading_deg - h + 180.0) % 360.0 - 180.0), 4))
    return err_mm, err_deg, sum(1 for st in ws.parts if st.dropped)


def summary_of(result: PickPlaceResult, p: PickPlaceParams, error: str | None,
               errors: tuple[list[float], list[float], int] | None) -> dict[str, Any]:
    placed = [c for c in result.cycles if c.placed]
    cycle_ms = [round(c.cycle_ms, 3) for c in placed]
    floor_ms = [round(c.floor_ms, 3) for c in placed]
    ratio = [c / f for c, f in zip(cycle_ms, floor_ms, strict=True) if f > 0]
    out: dict[str, Any] = {
        "app": "pickplace", "parts": p.parts, "parts_placed": len(placed),
        "parts_failed": len(result.cycles) - len(placed),
        "place_error_mm": [] if errors is None else errors[0],
        "place_error_deg": [] if errors is None else errors[1],
        "parts_dropped": None if errors is None else errors[2],
        "cycle_ms": cycle_ms, "floor_ms": floor_ms,
        "median_cycle_over_floor": round(statistics.median(ratio), 4) if ratio else None,
        "attempts": [c.attempts for c in result.cycles], "error": error,
    }
    return out


def write_figures(result: PickPlaceResult, run_dir: Path) -> list[str]:
    """``gantt.png`` (the phases of one cycle: the median one) and ``cycle_hist.png``; the names written."""
    placed = [c for c in result.cycles if c.placed]
    if not placed:
        return []
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    one = sorted(placed, key=lambda c: c.cycle_ms)[len(placed) // 2]
    fig, ax = plt.subplots(figsize=(8, 2.6))
    names = [s[0] for s in one.steps]
    for i, (_, t0, t1) in enumerate(one.steps):
        ax.barh(i, (t1 - t0) * 1000.0, left=(t0 - one.t_start_s) * 1000.0, color="C%d" % (i % 10))
    ax.set_yticks(range(len(names)), names)
    ax.invert_yaxis()
    ax.set_xlabel("ms from the cycle's start")
    ax.set_title(f"part {one.index + 1}: cycle {one.cycle_ms:.0f} ms, floor {one.floor_ms:.0f} ms")
    fig.tight_layout()
    fig.savefig(run_dir / "gantt.png", dpi=110)
    plt.close(fig)
    written.append("gantt.png")
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.hist([c.cycle_ms for c in placed], bins=min(30, max(5, len(placed))), color="C0", label="cycle")
    ax.axvline(statistics.median(c.floor_ms for c in placed), color="C3", ls="--", label="median floor")
    ax.set_xlabel("ms per part")
    ax.set_ylabel("parts")
    ax.legend()
    fig.tight_layout()
    fig.savefig(run_dir / "cycle_hist.png", dpi=110)
    plt.close(fig)
    written.append("cycle_hist.png")
    return written


async def run_pickplace_once(cfg: CellConfig, run_dir: Path, *, interrupter: Any = None,
                             locator: Callable[[Any, CellConfig], Any] | None = None,
                             params: PickPlaceParams | None = None) -> PickPlaceOutcome:
    """Connect to the cell's robot server and vision node, pick and place, save the run folder; see the module
    docstring. ``locator(comm, cfg)`` makes the locator from the vision communicator and the cell with its resolved
    addresses (default :class:`BusLocator`; an async context manager is entered for the run).
    Raises what the run raised after the folder is saved (PickPlaceError for the app's own faults)."""
    from aioadept import __version__
    from aioadept.bus import Communicator
    from aioadept.bus.endpoints import is_none, opposite
    from aioadept.runs.capture import Recorder, write_atomic
    from aioadept.client import RobotClient
    from aioadept.record.hook import MarkTee, open_run_recording, open_state_tap, write_run_mcap_of

    p = params or cfg.pickplace or PickPlaceParams()
    world = cfg.world
    if world is None or world.pallet is None:
        raise PickPlaceError("the cell has no pallet ([world.pallet]): pick and place needs its slots")
    recorder = Recorder()
    rrd = open_run_recording(cfg, run_dir, recorder)
    state_tap = open_state_tap(cfg)  # the robot's state messages for run.mcap; None when not wanted
    observers = [recorder] if rrd is None else [recorder, rrd]
    result = PickPlaceResult()
    error: str | None = None
    errors = None
    connected = False
    started = _dt.datetime.now(_dt.timezone.utc).isoformat()
    summary: dict[str, Any] = {}
    try:
        async with contextlib.AsyncExitStack() as stack:
            rc = await stack.enter_async_context(RobotClient(
                cfg.robot.host, cfg.robot.port, connect_timeout_s=cfg.robot.connect_timeout_s,
                ack_timeout_s=max(cfg.robot.ack_timeout_s, p.part_timeout_s + 10.0), observers=observers,
                hello_timeout_s=cfg.robot.hello_timeout_s or None, stop_port=stop_port_of(cfg)))
            connected = True
            watch = None
            if not is_none(cfg.robot.state_endpoint):
                watch = await stack.enter_async_context(WorldWatch(cfg.robot.state_endpoint))
            comm = await stack.enter_async_context(Communicator(
                opposite(cfg.vision.request_endpoint), opposite(cfg.vision.response_endpoint),
                timeout_s=p.locate_timeout_s, observers=observers, queries=cfg.bus.zenoh_queries))
            await stack.enter_async_context(_guarded(interrupter, rc))
            loc = (locator or (lambda c, _cfg: BusLocator(c, timeout_s=p.locate_timeout_s)))(comm, cfg)
            if hasattr(loc, "__aenter__"):
                loc = await stack.enter_async_context(loc)
            try:
                result = await pickplace(rc, loc, p, pallet=world.pallet, feeder=world.feeder,
                                         table_z_mm=world.table_z_mm,
                                         recorder=recorder if rrd is None else MarkTee(recorder, rrd))
            except BaseException as exc:
                result = getattr(exc, "result", result)
                raise
            finally:
                if watch is not None and connected:
                    ws = await asyncio.shield(watch.fresh())
                    if ws is not None:
                        errors = place_errors(ws, result, world.pallet)
    except BaseException as exc:
        error = run_error(exc)
        if not connected:  # nothing happened that a run folder could keep: leave none behind
            await abandon_run(run_dir, rrd, state_tap)
        raise
    finally:
        if connected:
            summary = summary_of(result, p, error, errors)
            meta = {"app": "pickplace", "aioadept_version": __version__, "started_utc": started,
                    "cell": cfg.to_dict(), "error": error}
            try:
                write_atomic(run_dir / "summary.json", json.dumps(summary, indent=2))
                write_atomic(run_dir / "pickplace.json", json.dumps(
                    {"cycles": [{"index": c.index, "slot": c.slot, "placed": c.placed, "attempts": c.attempts,
                                 "cycle_ms": c.cycle_ms, "floor_ms": c.floor_ms, "locate_ms": c.locate_ms,
                                 "motion_s": c.motion_s, "hand_s": c.hand_s,
                                 "steps": [[n, t0 - c.t_start_s, t1 - c.t_start_s] for n, t0, t1 in c.steps]}
                                for c in result.cycles]}, indent=1))
                recorder.save(run_dir, metadata=meta)
                write_figures(result, run_dir)
            except Exception as exc:  # a run folder that cannot be written must not hide the run's own error
                log.error("run folder %s not fully written: %s", run_dir, exc)
            if rrd is not None:
                await asyncio.shield(rrd.aclose())
            state = None if state_tap is None else await asyncio.shield(state_tap.stop())
            mcap_error = await asyncio.shield(asyncio.to_thread(write_run_mcap_of, cfg, run_dir, recorder, meta,
                                                                state))
            if mcap_error is not None:
                log.error("run.mcap not written: %s", mcap_error)
    return PickPlaceOutcome(run_dir, summary, error)
