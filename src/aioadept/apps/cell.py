"""Running a cell: the nodes a :class:`~aioadept.cell.config.CellConfig` starts on this machine (their ports,
command lines and world file), one focus run in a run folder, and the running cell of ``aioadept demo`` and
``aioadept focus``.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import datetime as _dt
import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aioadept.ports import free_port
from aioadept.apps.focus import FocusParams
from aioadept.apps.paper import FocusResult, ufloop
from aioadept.apps.processes import NodeProcess, run_watched
from aioadept.cell.bus import transport_argv, with_transport, zenoh_session
from aioadept.cell.config import CellConfig
from aioadept.defaults import ROBOT_PORT, STOP_PORT, STOP_PORT_OFFSET
from aioadept.runs.folder import abandon_run, merged_save_error, run_error, save_run
from aioadept.vision.options import VisionOptions

log = logging.getLogger(__name__)


def _with_free_port(endpoint: str) -> str:
    # tcp://HOST:0 -> tcp://HOST:<free port>, so we know the address before the node binds it.
    prefix, _, port = endpoint.rpartition(":")
    if port in ("0", "*"):
        host = prefix.split("//", 1)[-1]
        return f"{prefix}:{free_port(host)}"
    return endpoint


def resolve_ports(cfg: CellConfig) -> CellConfig:
    """Replace port 0 by free ports for the nodes this machine starts (and the Zenoh router's port 0 when this
    machine starts it), and apply the cell's transport (:func:`aioadept.cell.bus.with_transport`)."""
    if cfg.bus.zenoh and cfg.bus.start_router and cfg.bus.zenoh_router.endswith(":0"):
        host = cfg.bus.zenoh_router[len("tcp/"):].rpartition(":")[0]
        cfg = dataclasses.replace(cfg, bus=dataclasses.replace(cfg.bus, zenoh_router=f"tcp/{host}:{free_port(host)}"))
    cfg = with_transport(cfg)
    cfg = dataclasses.replace(cfg, robot=dataclasses.replace(cfg.robot), vision=dataclasses.replace(cfg.vision))
    if cfg.robot.start_sim:
        if cfg.robot.port == 0:
            cfg.robot.port = free_port(cfg.robot.host)
            if cfg.robot.stop_port == 0:
                cfg.robot.stop_port = free_port(cfg.robot.host)
        cfg.robot.state_endpoint = _with_free_port(cfg.robot.state_endpoint)
    if cfg.vision.start:
        cfg.vision.request_endpoint = _with_free_port(cfg.vision.request_endpoint)
        cfg.vision.response_endpoint = _with_free_port(cfg.vision.response_endpoint)
    return cfg


def stop_port_of(cfg: CellConfig) -> int:
    """The robot server's stop port: the cell file's ``stop_port``, else the robot port + 1."""
    return cfg.robot.stop_port or cfg.robot.port + STOP_PORT_OFFSET


def sim_argv(cfg: CellConfig, world_file: Path | None = None) -> list[str]:
    """The sim's command line; ``world_file``: the cell's world as a file (:func:`write_world_file`)."""
    r = cfg.robot
    world = ["--world", str(world_file)] if world_file is not None else []
    if "--vplus" in r.sim_args:
        # The V+ program opens its own ports (rs.port, rs.sport in vplus/rsconfig.V2: the defaults): map them to
        # the cell's. A --map-port of the user's in sim_args comes later and wins.
        ports = ["--map-port", f"{ROBOT_PORT}={r.port}", "--map-port", f"{STOP_PORT}={stop_port_of(cfg)}"]
    else:
        ports = ["--port", str(r.port), "--stop-port", str(stop_port_of(cfg))]
    return ["sim", "--host", r.host, *ports, "--time-scale", str(r.time_scale),
            "--monitor-speed", str(r.monitor_speed), "--state-endpoint", r.state_endpoint, "--robot-model", r.model,
            *world,
            *transport_argv(cfg), *r.sim_args]


def write_world_file(cfg: CellConfig, folder: Path) -> Path | None:
    """Write the cell's world as ``folder/world.json`` for the nodes a starter runs (``--world``); None without a
    world. The same table the cell file holds (:func:`aioadept.cell.world.world_to_table`)."""
    if cfg.world is None:
        return None
    from aioadept.runs.capture import write_atomic
    from aioadept.cell.world import world_to_table

    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "world.json"
    write_atomic(path, json.dumps(world_to_table(cfg.world), indent=1))
    return path


def vision_argv(cfg: CellConfig, world_file: Path | None = None) -> list[str]:
    """The node's command line: the addresses of the cell, then every ``[vision]`` option not at its default
    (``world_file``: the cell's world, :func:`write_world_file`, for a ``world`` source without its own file)."""
    v = cfg.vision
    argv = ["vision", "--state-endpoint", cfg.robot.state_endpoint,
            "--request-endpoint", v.request_endpoint, "--response-endpoint", v.response_endpoint,
            "--focus-offset-mm", str(v.focus_offset_mm), "--fps", str(v.fps), "--policy", v.policy,
            "--trigger", v.trigger, "--exposure-ms", str(v.exposure_ms), "--pixel-format", v.pixel_format]
    for spec in v.sources():
        argv += ["--source", spec]
    written = {"state_endpoint", "request_endpoint", "response_endpoint", "focus_offset_mm", "fps", "policy",
               "trigger", "exposure_ms", "pixel_format", "source"}
    default = VisionOptions()
    for f in dataclasses.fields(VisionOptions):
        value = getattr(v, f.name)
        if f.name in written or value == getattr(default, f.name) or value is None:
            continue
        flag = "--" + f.name.replace("_", "-")
        if isinstance(value, bool):
            argv += [flag] if value else []
        elif isinstance(value, list):
            for item in value:
                argv += [flag, str(item)]
        else:
            argv += [flag, str(value)]
    if world_file is not None and not v.world and "world" in v.sources():
        argv += ["--world", str(world_file)]
    return [*argv, *transport_argv(cfg), *v.vision_args]


def new_run_dir(cfg: CellConfig, base: Path | None = None) -> Path:
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S-%f")[:-3]
    name = cfg.run.name or f"focus-s{cfg.focus.approach_speed}-dz{cfg.focus.delta_z_mm:g}"
    d = (base or Path(cfg.run.out_dir)) / f"{stamp}-{name}"
    d.mkdir(parents=True, exist_ok=False)
    return d


@dataclass(frozen=True, slots=True)
class RunOutcome:
    run_dir: Path
    result: FocusResult | None
    error: str | None
    save_error: OSError | None = None
    """Files of the run folder that could not be written (:class:`aioadept.errors.RunSaveError`), if any."""


async def run_focus_once(cfg: CellConfig, run_dir: Path, *, params: FocusParams | None = None,
                         interrupter: Any = None) -> RunOutcome:
    """Connect to the robot server and the vision node of ``cfg``, run :func:`ufloop` once, record and save it.

    ``interrupter`` (:class:`aioadept.apps.interrupt.Interrupter`) gets the robot connection, so Ctrl-C stops the
    robot. Saving never hides the result: a run folder that cannot be written is reported in
    ``RunOutcome.save_error`` (the result is still returned), and after a failed run it is logged while the run's
    own error propagates.
    """
    from aioadept import __version__
    from aioadept.bus import Communicator
    from aioadept.bus.endpoints import opposite
    from aioadept.runs.capture import Recorder
    from aioadept.client import RobotClient

    from aioadept.record.hook import MarkTee, open_run_recording, open_state_tap, write_run_mcap_of

    params = params or cfg.focus
    recorder = Recorder()
    rrd = open_run_recording(cfg, run_dir, recorder)  # run.rrd / live view; None when off or Rerun is missing
    state_tap = open_state_tap(cfg)  # the robot's state messages for run.mcap; None when not wanted
    observers = [recorder] if rrd is None else [recorder, rrd]
    result: FocusResult | None = None
    error: str | None = None
    save_error: OSError | None = None
    started = _dt.datetime.now(_dt.timezone.utc).isoformat()
    connected = False
    try:
        async with RobotClient(cfg.robot.host, cfg.robot.port, connect_timeout_s=cfg.robot.connect_timeout_s,
                               ack_timeout_s=cfg.robot.ack_timeout_s, observers=observers,
                               hello_timeout_s=cfg.robot.hello_timeout_s or None,
                               stop_port=stop_port_of(cfg)) as rc:
            connected = True
            async with Communicator(opposite(cfg.vision.request_endpoint), opposite(cfg.vision.response_endpoint),
                                    timeout_s=params.vision_timeout_s, observers=observers,
                                    queries=cfg.bus.zenoh_queries) as comm, \
                    _guarded(interrupter, rc):
                marks = recorder if rrd is None else MarkTee(recorder, rrd)
                if params.mode == "sweep":
                    result = await _sweep(cfg, rc, comm, params, marks)
                else:
                    result = await ufloop(rc, comm, params.delta_z_mm, params.approach_speed,
                                          max_steps=params.max_steps, vision_timeout_s=params.vision_timeout_s,
                                          retract_speed=params.retract_speed, recorder=marks)
    except BaseException as exc:
        error = run_error(exc)
        if not connected:  # nothing happened that a run folder could keep: leave none behind
            await abandon_run(run_dir, rrd, state_tap)
        raise
    finally:
        if connected:  # (else the run folder is gone, above, and the connect error propagates)
            meta = {
                "app": "focus", "aioadept_version": __version__, "started_utc": started,
                "mode": params.mode, "approach_speed": params.approach_speed, "delta_z_mm": params.delta_z_mm,
                "max_steps": params.max_steps, "cell": cfg.to_dict(), "error": error,
                "result": None if result is None else focus_result_dict(result),
            }
            save_error = save_run(recorder, run_dir, meta)
            if result is not None and result.mode == "sweep" and cfg.run.analyze:
                save_error = _sweep_figure(meta["result"], run_dir, save_error)
            if save_error is not None and result is None:
                log.error("%s", save_error)  # the run's own error propagates; this one must not vanish either
            if rrd is not None:
                await asyncio.shield(rrd.aclose())  # flushed and closed even when the run was cancelled
                if rrd.error is not None and rrd.rrd_path is not None:  # e.g. a full disk: named with the others
                    save_error = merged_save_error(save_error, run_dir, {rrd.rrd_path.name: rrd.error})
            # run.mcap after run.rrd: from the same records as robot.csv/vision.csv, off the loop (it reads frames).
            state = None if state_tap is None else await asyncio.shield(state_tap.stop())
            mcap_error = await asyncio.shield(asyncio.to_thread(write_run_mcap_of, cfg, run_dir, recorder, meta,
                                                                state))
            if mcap_error is not None:
                save_error = merged_save_error(save_error, run_dir, {"run.mcap": mcap_error})
    return RunOutcome(run_dir, result, error, save_error)


async def _sweep(cfg: CellConfig, rc: Any, comm: Any, params: FocusParams, marks: Any) -> FocusResult:
    """:func:`aioadept.apps.sweep.sweep_focus` with the cell's camera exposure and robot state stream (the sim's,
    or ``aioadept state`` relaying a controller's; none: the frames are placed by the planned profile)."""
    from aioadept.apps.sweep import sweep_focus
    from aioadept.bus.endpoints import is_none

    endpoint = None if is_none(cfg.robot.state_endpoint) else cfg.robot.state_endpoint  # as the vision node's
    curve = None
    if endpoint is not None and (cfg.vision.state_curve_secret or cfg.vision.state_curve_server):
        from aioadept.vision.service import _state_curve

        curve = _state_curve(cfg.vision)
    return await sweep_focus(rc, comm, params, exposure_ms=cfg.vision.exposure_ms, state_endpoint=endpoint,
                             state_curve=curve, vision_timeout_s=params.vision_timeout_s, recorder=marks,
                             time_scale=sim_time_scale(cfg))


def sim_time_scale(cfg: CellConfig) -> float:
    """The robot's speed-up as the cell file gives it (``[robot] time_scale``, 1: a real controller): the sim this
    cell starts runs at it, and a sweep assumes it when the robot's status does not report one (the V+ server)."""
    return cfg.robot.time_scale


SWEEP_FIGURE = "fig09b_sweep.png"


def _sweep_figure(result: dict[str, Any], run_dir: Path, save_error: OSError | None) -> OSError | None:
    """The sweep's figure (sharpness against position, the fit, the plane +- sigma) beside focus.json; skipped
    without matplotlib (the [analysis] extra), named with the files not written when the disk refuses it."""
    try:
        from aioadept.analysis.plots import plot_sweep
    except ImportError:
        log.info("no %s: matplotlib is not installed (the [analysis] extra)", SWEEP_FIGURE)
        return save_error
    try:
        plot_sweep(result, run_dir / SWEEP_FIGURE, title=f"Focus sweep: sharpness along tool z\n{run_dir.name}")
    except OSError as exc:
        return merged_save_error(save_error, run_dir, {SWEEP_FIGURE: exc.strerror or str(exc)})
    return save_error


@contextlib.asynccontextmanager
async def _guarded(interrupter: Any, robot: Any):  # noqa: ANN202
    if interrupter is None:
        yield robot
    else:
        async with interrupter.guard(robot):
            yield robot


def focus_result_dict(r: FocusResult) -> dict[str, Any]:
    """focus.json: the result; both modes write ``mode`` and ``search_s``, a sweep its fit and frames too."""
    out: dict[str, Any] = {
        "inspection_pose": dataclasses.asdict(r.inspection_pose),
        "approach_pose": dataclasses.asdict(r.approach_pose),
        "sharpness": list(r.sharpness), "peak_index": r.peak_index, "delta_z_mm": r.delta_z_mm,
        "peak_offset_mm": r.peak_offset_mm, "steps": r.steps, "mode": r.mode, "search_s": r.search_s,
    }
    if r.mode == "sweep":
        out.update({"peak_sigma_mm": r.peak_sigma_mm, "pose_source": r.pose_source, "frames": list(r.frames),
                    "sweep": r.sweep})
    return out


class Cell:
    """The running nodes of a cell and its resolved addresses; :meth:`run` supervises a coroutine against them."""

    def __init__(self, cfg: CellConfig, nodes: list[NodeProcess]) -> None:
        self.cfg = cfg
        self.nodes = nodes

    async def run(self, coro: Any) -> Any:
        """Await ``coro``; if a node dies first, cancel it and raise :class:`~aioadept.errors.NodeError`
        (:func:`~aioadept.apps.processes.run_watched`: the run folder names the node)."""
        return await run_watched(coro, *self.nodes)


@contextlib.asynccontextmanager
async def running_cell(cfg: CellConfig, log_dir: Path, *, own_session: bool = True):
    """Start the nodes of ``cfg`` that run on this machine and yield a :class:`Cell` with resolved addresses.

    The nodes are stopped on exit (SIGINT, then SIGTERM, then SIGKILL), whatever happened. ``own_session=False``:
    this process's Zenoh session is opened and closed by the caller (several cells sharing one router,
    :mod:`aioadept.apps.multicell`).
    """
    cfg = resolve_ports(cfg)
    nodes: list[NodeProcess] = []
    world_file = write_world_file(cfg, log_dir) if cfg.robot.start_sim or cfg.vision.start else None
    async with contextlib.AsyncExitStack() as stack:
        # Zenoh: this process is the cell's router (or a client of it) before any node connects to it; the
        # session closes after the nodes have stopped.
        if own_session:
            stack.enter_context(zenoh_session(cfg))
        if cfg.robot.start_sim:
            sim = await stack.enter_async_context(NodeProcess("sim", sim_argv(cfg, world_file),
                                                              log_path=log_dir / "sim.log"))
            cfg.robot.port = int(sim.ready.get("port", cfg.robot.port))
            cfg.robot.host = sim.ready.get("host", cfg.robot.host)
            nodes.append(sim)
        if cfg.vision.start:
            vis = await stack.enter_async_context(
                NodeProcess("vision", vision_argv(cfg, world_file), log_path=log_dir / "vision.log"))
            # READY gives the MCN's side of each link; the cell keeps the node's side (real ports, explicit roles).
            from aioadept.bus.endpoints import opposite

            cfg.vision.request_endpoint = opposite(vis.ready.get("request", opposite(cfg.vision.request_endpoint)))
            cfg.vision.response_endpoint = opposite(vis.ready.get("response",
                                                                  opposite(cfg.vision.response_endpoint)))
            nodes.append(vis)
        yield Cell(cfg, nodes)
