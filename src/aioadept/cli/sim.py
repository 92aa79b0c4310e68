"""``aioadept sim``: run the simulated Adept controller (RobotServer + Viper s850) until SIGINT/SIGTERM.

Prints ``READY host=H port=P state=ENDPOINT`` on stdout once it listens (the real port when started with
``--port 0``; ``state=none`` without a state stream), so starters wait for that line instead of sleeping.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import signal
import sys

from aioadept import defaults
from aioadept.cli.options import (ArgumentParser, DefaultsHelpFormatter, Listener, add_insecure_option,
                                  add_node_transport_options, check_listeners, zenoh_listener, zmq_listener,
                                  apply_cell_bus, apply_node_transport, description)
from aioadept.geometry import NULL, Pose
from aioadept.robots.base import JumpLimit
from aioadept.sim.line import CartesianLimits
from aioadept.sim.server import DEFAULT_PORT, DEFAULT_STATE_ENDPOINT, Faults, SimOptions, SimServer


def _six(text: str) -> tuple[float, ...]:
    vals = tuple(float(v) for v in text.split(","))
    if len(vals) != 6:
        raise argparse.ArgumentTypeError(f"expected 6 comma-separated numbers, got {text!r}")
    return vals


def _jump_limit(text: str) -> JumpLimit | None:
    if text.strip().lower() == "off":
        return None
    try:
        floor, per_mm, per_deg = (float(v) for v in text.split(","))
        return JumpLimit(floor, per_mm, per_deg)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected FLOOR,PER_MM,PER_DEG (three numbers >= 0) or 'off', got {text!r}") from exc


def _robot_model(text: str) -> str:
    from aioadept.robots import model

    try:
        return model(text).name
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _hand(text: str):  # -> aioadept.sim.io.HandConfig
    from aioadept.sim.io import HandConfig

    try:
        vals = [float(v) for v in text.split(",")]
        if len(vals) not in (3, 4) or any(v != int(v) for v in vals[:3]):
            raise ValueError("expected OPEN,CLOSE,SWITCH[,CLOSE_TIME_S] (signal numbers; SWITCH 0 = none)")
        return HandConfig(int(vals[0]), int(vals[1]), int(vals[2]) or None,
                          *(vals[3:] if len(vals) == 4 else ()))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--hand {text!r}: {exc}") from None


def _cartesian_speed(text: str) -> CartesianLimits:
    try:
        vals = [float(v) for v in text.split(",")]
        if len(vals) not in (1, 2):
            raise ValueError(text)
        return CartesianLimits(*vals)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected MM_S[,DEG_S] (numbers > 0), got {text!r}") from exc


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="aioadept sim", description=description(__doc__),
                                formatter_class=DefaultsHelpFormatter)
    p.add_argument("--config", metavar="FILE",
                   help="cell file (examples/cell.toml): its [robot] table gives host, port, time_scale, "
                        "monitor_speed, state_endpoint and sim_args, its [bus] table the transport (on zenoh: the "
                        "cell, the router to connect to, and the state stream on the cell's key, as the demo's "
                        "application expects it); the whole file is checked as demo checks it; options given here "
                        "override it")
    p.add_argument("--host", default=defaults.ROBOT_HOST,
                   help="address to bind; beyond loopback needs --insecure (the robot protocol authenticates "
                        "nobody: whoever reaches the port may move the arm; --allow does not authenticate)")
    add_insecure_option(p)
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help="TCP port (0: pick a free one)")
    p.add_argument("--time-scale", type=float, default=1.0, dest="time_scale",
                   help="motions run this many times faster (the ack clock stays real time)")
    p.add_argument("--instant", action="store_true", help="motions complete at once (for tests)")
    p.add_argument("--monitor-speed", type=float, default=100.0, dest="monitor_speed",
                   help="controller monitor speed in %% (effective speed = program speed x this / 100)")
    p.add_argument("--max-speed", type=float, default=100.0, dest="max_speed",
                   help="cap on the effective speed in %% (a safety limit: no motion runs faster)")
    p.add_argument("--joint-jump-limit", type=_jump_limit, default="2,1,3", dest="jump_limit",
                   metavar="FLOOR,PER_MM,PER_DEG",
                   help="refuse (JOINT_JUMP) a Cartesian target for which a joint would turn more than FLOOR + PER_MM "
                        "x mm + PER_DEG x degrees of the move, e.g. a wrist flip from a 2 mm step; 'off' disables")
    p.add_argument("--cartesian-speed", type=_cartesian_speed, default="2000,360", dest="cartesian_speed",
                   metavar="MM_S[,DEG_S]",
                   help="what 100 %% speed means for a straight line (move_to_s, MOVES): the tool's speed in mm/s "
                        "and its turn in deg/s")
    p.add_argument("--max-clients", type=int, default=16, dest="max_clients",
                   help="connections served at once; more are refused with a SERVER_BUSY error ack")
    p.add_argument("--max-queued", type=int, default=defaults.MAX_QUEUED, dest="max_queued", metavar="N",
                   help="commands one connection may have queued; more are refused with a SERVER_BUSY error ack "
                        "at once (64: the shipped V+ server's limit)")
    p.add_argument("--allow", action="append", default=[], metavar="ADDR",
                   help="accept clients only from this IP address (repeatable; default: any)")
    p.add_argument("--line-timeout", type=float, default=10.0, dest="line_timeout",
                   help="close a connection that is in the middle of a line and receives nothing for this many "
                        "seconds, or whose line is still incomplete 6 times as long after its first byte (0: never)")
    p.add_argument("--stop-port", default="auto", dest="stop_port", metavar="PORT",
                   help="the stop port: serves only stop, here and hello, so a stop gets in with every client slot "
                        "taken ('auto': --port + 1, or a free port with --port 0; 'none': no stop port)")
    p.add_argument("--stop-window", type=float, default=1.0, dest="stop_window",
                   help="over --max-clients, a new connection may still send stop for this many seconds (the "
                        "reserved stop path); anything else is refused")
    p.add_argument("--state-curve-secret", metavar="FILE", dest="state_curve_secret",
                   help="CURVE: the sim's secret certificate (NAME.key_secret); encrypts the state stream and admits "
                        "only subscribers that know the sim's public key (docs/security.md)")
    p.add_argument("--state-curve-allow", action="append", default=[], metavar="FILE", dest="state_curve_allow",
                   help="CURVE: public certificate (NAME.key) of a subscriber allowed in (repeatable)")
    p.add_argument("--state-endpoint", default=DEFAULT_STATE_ENDPOINT, dest="state_endpoint",
                   help="ZeroMQ PUB endpoint of the robot state stream ('none' to disable)")
    p.add_argument("--state-rate-hz", type=float, default=100.0, dest="state_rate_hz",
                   help="robot state samples per second")
    p.add_argument("--fault", action="append", default=[], metavar="SPEC",
                   help="inject a fault: ack-delay=SECONDS, drop-after=N (messages), silent (repeatable); for "
                        "tests only: raise=POINT, a bug of the server itself (executor, reader, world, callback, "
                        "state-send; docs/sim.md)")
    p.add_argument("--tool", type=_six, default=None, metavar="X,Y,Z,YAW,PITCH,ROLL",
                   help="TOOL transform (mm, degrees); default NULL")
    p.add_argument("--joints", type=_six, default=None, metavar="J1,...,J6",
                   help="initial joint values in degrees, a SCARA's J3 in mm, J5 and J6 0 on a four-axis arm "
                        "(default: the model's home, 0,-90,180,0,90,0 on a Viper)")
    p.add_argument("--robot-model", type=_robot_model, default="viper-s850", dest="robot_model", metavar="NAME",
                   help="the arm: viper-s850 (default), viper-s650, cobra-s600, cobra-s800 (docs/sim.md, Robot "
                        "models); the cell file's [robot] model")
    p.add_argument("--hand", type=_hand, default=None, metavar="OPEN,CLOSE,SWITCH[,CLOSE_TIME_S]",
                   help="the hand's open and close valve outputs and closed-fully switch input (0: none), and its "
                        "travel time; default 1,2,1001,0.04")
    p.add_argument("--hand-time", type=float, default=None, dest="hand_time", metavar="SECONDS",
                   help="V+ HAND.TIME: how long open_hand/close_hand/relax_hand hold (a V+ program's PARAMETER "
                        "HAND.TIME overrides it); default 0.05")
    p.add_argument("--world", metavar="FILE", default=None,
                   help="the simulated world (parts, feeder sensor, pallet; docs/sim.md): a cell file's [world] "
                        "table, or a .json file holding that table (--config reads the cell file's [world] too)")
    p.add_argument("--log-level", default="WARNING", dest="log_level", help="logging level on stderr")
    v = p.add_argument_group("V+ emulator (instead of the Python skill table; docs/vplus.md)")
    v.add_argument("--vplus", nargs="+", metavar="FILE", default=None,
                   help="run these V+ .V2 modules in the emulator; the Python skill table is not used")
    v.add_argument("--run", metavar="PROGRAM", default=None, help="with --vplus: the program to run in task 0")
    v.add_argument("--map-port", action="append", default=[], metavar="VPORT=HOSTPORT", dest="map_port",
                   help="with --vplus: FOPEN /LOCAL_PORT VPORT binds HOSTPORT instead (0: ephemeral; repeatable)")
    v.add_argument("--vplus-cycle", type=float, default=0.016, dest="vplus_cycle", metavar="SECONDS",
                   help="with --vplus: the trajectory cycle that WAIT waits for")
    v.add_argument("--strict", action="store_true",
                   help="with --vplus: refuse to serve (exit 2) when a module has a line that does not load")
    v.add_argument("--disk", metavar="DIR", default=None,
                   help="with --vplus: the folder that holds the program's disk files (FOPENR, FOPENW, ...); "
                        "nothing outside it is reachable; default a new temporary folder")
    v.add_argument("--debug-port", type=int, default=None, dest="debug_port", metavar="PORT",
                   help="with --vplus: serve V+ debugger (Debug Adapter Protocol) attach sessions on 127.0.0.1:PORT "
                        "(docs/vplus.md, Debugging)")
    v.add_argument("--tcp-send-buffer", type=int, default=None, dest="tcp_send_buffer", metavar="BYTES",
                   help="with --vplus, for tests: each TCP connection's socket send buffer (SO_SNDBUF) and the "
                        "emulator's output buffer are BYTES (1024..16777216), so that a peer that does not read "
                        "backs the V+ program's output up after a few KiB, as on a controller (docs/vplus.md)")
    add_node_transport_options(p)
    return p


def _state_curve(args: argparse.Namespace):  # -> CurveServer | None
    if not args.state_curve_secret:
        if args.state_curve_allow:
            raise ValueError("--state-curve-allow needs --state-curve-secret")
        return None
    from aioadept.bus.security import CurveServer, load_keypair

    keys = load_keypair(args.state_curve_secret)
    if keys.secret is None:
        raise ValueError(f"{args.state_curve_secret} holds no secret key (give the .key_secret file)")
    allowed = [load_keypair(f).public for f in args.state_curve_allow] or None
    return CurveServer(keys, allowed_clients=allowed)


def check_exposure(args: argparse.Namespace) -> None:
    """The listeners of ``aioadept sim`` through the one check (:func:`aioadept.cli.options.check_listeners`)."""
    listeners = [Listener("--host", args.host, False, "move the robot"),
                 *zmq_listener("--state-endpoint", args.state_endpoint, True, bool(args.state_curve_secret),
                               "read the robot's state"),
                 *zenoh_listener(vars(args), "read and publish the cell's streams")]
    check_listeners("aioadept sim", listeners, args.insecure)


def stop_port_of(value: str, port: int) -> int | None:
    """``--stop-port``: 'auto' (port + 1; 0 with --port 0), 'none', or a port number. Raises ``ValueError``."""
    if value.lower() == "none":
        return None
    if value.lower() == "auto":
        return port + defaults.STOP_PORT_OFFSET if port else 0
    try:
        n = int(value)
    except ValueError:
        raise ValueError(f"--stop-port: {value!r} is not a port number, 'auto' or 'none'") from None
    if not 0 <= n <= 0xFFFF:
        raise ValueError(f"--stop-port: {n} is not a TCP port number (0..65535)")
    return n


def options_from_args(args: argparse.Namespace) -> SimOptions:
    """Raises ``ValueError`` for inconsistent values."""
    from aioadept.bus.endpoints import is_none

    state = None if is_none(args.state_endpoint) else args.state_endpoint
    extra = {}
    if args.joints is not None:
        extra["joints_deg"] = args.joints
    if args.hand is not None:
        extra["hand"] = args.hand
    if getattr(args, "world_config", None) is not None:
        extra["world"] = args.world_config
    if args.hand_time is not None:
        from aioadept.sim.io import MAX_HAND_TIME_S

        if not 0 <= args.hand_time <= MAX_HAND_TIME_S:
            raise ValueError(f"--hand-time {args.hand_time:g}: outside 0..{MAX_HAND_TIME_S:g} s")
        extra["hand_time_s"] = args.hand_time
    return SimOptions(host=args.host, port=args.port, stop_port=stop_port_of(args.stop_port, args.port),
                      time_scale=args.time_scale, instant=args.instant,
                      monitor_speed_pct=args.monitor_speed, max_speed_pct=args.max_speed,
                      jump_limit=args.jump_limit, cartesian_limits=args.cartesian_speed,
                      max_clients=args.max_clients, max_queued=args.max_queued, allow=tuple(args.allow),
                      line_timeout_s=args.line_timeout or None, stop_window_s=args.stop_window,
                      state_endpoint=state, state_rate_hz=args.state_rate_hz, faults=Faults.parse(args.fault),
                      state_curve=_state_curve(args),
                      tool=Pose(*args.tool) if args.tool else NULL, robot_model=args.robot_model, **extra)


async def run(options: SimOptions) -> int:
    """Serve until SIGINT/SIGTERM (exit status 0) or until a task of the server dies (:meth:`SimServer.die`: the
    arm braked, every connection closed, the stream showing the arm at rest; then one line on stderr naming the
    task and the exception with the file:line it was raised at, exit status 1)."""
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    sim = SimServer(options)
    try:
        async with sim:
            loop.set_exception_handler(sim.on_loop_error)  # after start: a bind error is no death
            state = sim.state_endpoint or "none"
            stop_port = sim.stop_port if sim.stop_port is not None else "none"
            from aioadept.bus.zenoh import announce_ready

            announce_ready()  # --transport zenoh: the node's liveliness token (no-op on ZeroMQ)
            print(f"READY host={sim.host} port={sim.port} state={state} stop_port={stop_port}", flush=True)
            stopped, died = asyncio.ensure_future(stop.wait()), asyncio.ensure_future(sim.dead.wait())
            try:
                await asyncio.wait({stopped, died}, return_when=asyncio.FIRST_COMPLETED)
            finally:
                for t in (stopped, died):
                    t.cancel()
    finally:
        loop.set_exception_handler(None)
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
    if sim.death is not None:
        from aioadept.errors import one_line

        task, exc = sim.death
        print(f"aioadept sim: {task} died of {one_line(exc)}; the arm was braked and every connection "
              f"closed", file=sys.stderr, flush=True)
        return 1
    return 0


_PYTHON_SERVER_ONLY = (
    ("max_clients", "--max-clients", "set rs.maxcli in its rsconfig.V2 (FOPEN /CLIENTS)"),
    ("max_queued", "--max-queued", "set rs.maxq in its rsconfig.V2"),
    ("allow", "--allow", "the program cannot see a peer's address; use the controller's network settings"),
    ("line_timeout", "--line-timeout", "set rs.lntmo in its rsconfig.V2 (0: off)"),
    ("stop_window", "--stop-window", "set rs.stmo in its rsconfig.V2 (the stop port's idle time)"),
    ("stop_port", "--stop-port", "set rs.sport in its rsconfig.V2 and map it with --map-port 1235=N"),
)
"""Options of the Python sim's TCP server that the V+ emulator's server (the V+ program) does not read: given with
--vplus they would be silently ignored, so they are refused, each with where its V+ counterpart lives."""


_ROBOT_TABLE = (("host", "host"), ("port", "port"), ("time_scale", "time_scale"),
                ("monitor_speed", "monitor_speed"), ("state_endpoint", "state_endpoint"), ("model", "robot_model"))
"""The cell file's [robot] keys this node reads: (key, argparse dest), and ``stop_port`` (0 = the port + 1, as
``--stop-port auto``). The rest of [robot] is the client's (start_sim, the timeouts)."""


def parse_args(parser: argparse.ArgumentParser, argv: list[str] | None) -> argparse.Namespace:
    """Defaults < the cell file's ``[robot]`` and ``[bus]`` tables (``--config``) < the command line. A bad file: one
    line, exit 2."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    from aioadept.cell.schema import report

    world = None
    if args.config:
        from aioadept.cell.config import CellConfig

        try:
            cell = CellConfig.from_toml(args.config)
        except (OSError, ValueError) as exc:
            raise SystemExit(report("aioadept sim", exc)) from None
        robot, world = cell.robot, cell.world
        parser.set_defaults(**{dest: getattr(robot, key) for key, dest in _ROBOT_TABLE},
                            stop_port=str(robot.stop_port) if robot.stop_port else "auto")
        args = parser.parse_args([*robot.sim_args, *argv])
        # [bus]: the transport and keys of the demo's application (a --state-endpoint of the command line's, one
        # that differs from the file's, is kept as given).
        given = {k for k in ("transport", "cell", "zenoh_connect", "zenoh_listen", "zenoh_config") if getattr(args, k)}
        if args.state_endpoint != robot.state_endpoint:
            given.add("state_endpoint")
        try:
            apply_cell_bus(vars(args), cell.bus, given, {"state_endpoint": ("sim", "state")}, args.config)
        except ValueError as exc:
            raise SystemExit(report("aioadept sim", exc)) from None
    if args.world:
        from aioadept.cell.world import load_world

        try:
            world = load_world(args.world)
        except (OSError, ValueError) as exc:
            raise SystemExit(report("aioadept sim", exc)) from None
    args.world_config = world
    return args


def _check_vplus_options(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """The options that only the V+ emulator has: refused (one line, exit 2) without --vplus or out of range."""
    if args.vplus is None and (args.run or args.map_port or args.disk or args.tcp_send_buffer is not None):
        parser.error("--run, --map-port, --disk and --tcp-send-buffer need --vplus")
    if args.tcp_send_buffer is not None and not 1024 <= args.tcp_send_buffer <= 1 << 24:
        parser.error(f"--tcp-send-buffer {args.tcp_send_buffer}: out of range (1024..16777216 bytes)")


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parse_args(parser, argv)
    _check_vplus_options(parser, args)
    if args.disk is not None and os.path.exists(args.disk) and not os.path.isdir(args.disk):
        parser.error(f"--disk {args.disk}: not a folder")
    if args.vplus is not None:
        if not args.run:
            parser.error("--vplus needs --run PROGRAM")
        for dest, flag, instead in _PYTHON_SERVER_ONLY:
            if getattr(args, dest) != parser.get_default(dest):
                parser.error(f"{flag} is an option of the Python sim's server; with --vplus the V+ program "
                             f"serves the connections: {instead}")
        from aioadept.vplus import cli as vplus_cli

        if any(f.partition("=")[0] == "raise" for f in args.fault):
            parser.error("--fault raise=POINT tests the Python sim's server; with --vplus the V+ program serves")
        try:
            vplus_cli.parse_port_map(args.map_port)
            apply_node_transport(vars(args), "sim", {"state_endpoint": (DEFAULT_STATE_ENDPOINT, "sim", "state")})
            options = options_from_args(args)     # the same robot, state stream and faults as the Python backend
            check_exposure(args)
        except ValueError as exc:
            parser.error(str(exc))
        try:
            return asyncio.run(vplus_cli.run(args, options))
        except Exception as exc:  # OSError (port taken), BusError (state endpoint taken)
            from aioadept.errors import AdeptError

            if isinstance(exc, (OSError, AdeptError)):
                print(f"aioadept sim: {exc}", file=sys.stderr)
                return 1
            raise
    from aioadept.cli.options import setup_logging

    setup_logging(args.log_level)
    try:
        apply_node_transport(vars(args), "sim", {"state_endpoint": (DEFAULT_STATE_ENDPOINT, "sim", "state")})
        options = options_from_args(args)
        check_exposure(args)
    except ValueError as exc:
        parser.error(str(exc))
    try:
        return asyncio.run(run(options))
    except OSError as exc:  # e.g. the port is taken
        print(f"aioadept sim: {exc}", file=sys.stderr)
        return 1
    except Exception as exc:  # BusError binding the state endpoint, etc.
        from aioadept.errors import AdeptError

        if isinstance(exc, AdeptError):
            print(f"aioadept sim: {exc}", file=sys.stderr)
            return 1
        raise


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
