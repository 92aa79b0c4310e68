"""The ``launch`` request of ``aioadept vplus dap`` (:mod:`aioadept.vplus.dap`): its arguments checked, and the
emulator it runs (real time, the sim's arm and the cell's world, TCP on 127.0.0.1)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from aioadept.errors import AdeptError

LAUNCH_KEYS = {"modules", "program", "task", "portMap", "timeScale", "disk", "cell", "stopOnEntry"}


class LaunchError(AdeptError, ValueError):
    """A bad ``launch`` argument: the message names the key."""


def launch_args(args: dict) -> dict:
    """The launch arguments checked, with defaults; :class:`LaunchError` naming a bad key."""
    unknown = set(args) - LAUNCH_KEYS - {"type", "request", "name", "__sessionId", "noDebug", "__configurationTarget"}
    if unknown:
        raise LaunchError(f"launch: unknown argument {sorted(unknown)[0]!r} (known: {', '.join(sorted(LAUNCH_KEYS))})")
    modules = args.get("modules")
    if not isinstance(modules, list) or not modules or not all(isinstance(m, str) for m in modules):
        raise LaunchError("launch: modules must be a list of .V2 file paths")
    program = args.get("program")
    if not isinstance(program, str) or not program:
        raise LaunchError("launch: program must name the V+ program to run (e.g. rs.main)")
    task = args.get("task", 0)
    if not isinstance(task, int) or not 0 <= task <= 27:
        raise LaunchError(f"launch: task {task!r}: must be a task number 0..27")
    pm = args.get("portMap") or {}
    if not isinstance(pm, dict):
        raise LaunchError("launch: portMap must be an object: V+ port -> host port")
    try:
        port_map = {int(k): int(v) for k, v in pm.items()}
    except (TypeError, ValueError):
        raise LaunchError("launch: portMap: ports must be numbers") from None
    if not all(0 < k < 65536 and 0 <= v < 65536 for k, v in port_map.items()):
        raise LaunchError("launch: portMap: port out of range")
    scale = args.get("timeScale", 1.0)
    if not isinstance(scale, (int, float)) or not scale > 0:
        raise LaunchError(f"launch: timeScale {scale!r}: must be > 0")
    return {"modules": modules, "program": program, "task": task, "portMap": port_map, "timeScale": float(scale),
            "disk": args.get("disk"), "cell": args.get("cell"), "stopOnEntry": bool(args.get("stopOnEntry"))}


def make_emulator(a: dict, console: Callable[[int, str], None], on_listen: Callable[[int, str, int], None]) -> Any:
    """The emulator of a launch, in real time, with the sim's arm (and the cell's world) and TCP on 127.0.0.1."""
    from aioadept.sim.server import SimOptions
    from aioadept.vplus import Emulator, RealClock
    from aioadept.vplus.iodev import Network
    from aioadept.vplus.loader import load_files
    from aioadept.vplus.parse import norm
    from aioadept.vplus.robot import RobotDevice

    world = None
    if a["cell"]:
        from aioadept.cell.world import load_world

        try:
            world = load_world(a["cell"])
        except (OSError, ValueError) as exc:
            raise LaunchError(f"launch: cell {a['cell']}: {exc}") from None
    try:
        module = load_files(a["modules"])
    except OSError as exc:
        raise LaunchError(f"launch: modules: {exc.filename or exc}: {exc.strerror or exc}") from None
    if norm(a["program"]) not in module.programs:
        raise LaunchError(f"launch: program {a['program']}: no such program in {', '.join(a['modules'])}")
    ctl = SimOptions(time_scale=a["timeScale"], state_endpoint=None, world=world).make_controller()
    emu = Emulator(module, robot=RobotDevice(ctl), clock=RealClock(), console=console, disk_dir=a["disk"])
    emu.rt.devices = Network("127.0.0.1", a["portMap"], on_listen)
    return emu
