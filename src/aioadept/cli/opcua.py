"""``aioadept opcua``: the robot as a plant's OPC UA client sees one, per the Robotics companion specification
(OPC 40010-1): a MotionDeviceSystem with the robot's axes, controller and safety state.

Follows the robot.state stream on ``--state-endpoint`` (the sim's, or a controller's through ``aioadept state``) and
asks the robot server at ``--robot`` for ``hello`` and ``status`` (docs/protocol.md 4.7), and serves them as an OPC UA
server at ``--endpoint``: each axis's ActualPosition and ActualSpeed (degrees, degrees per second) with the robot's
time as source timestamp, the E-stop, the server's name and version. What V+ does not say (the operating mode, a
protective stop, serial numbers nobody gave) is left Bad, never made up; a stream that stalls turns the live values
Uncertain within a second, and they are Good again when it comes back. Read-only unless ``--allow-commands``
(Stop and RunSkill, for the users of ``--users`` only). ``--security`` offers SecurityPolicy None and/or
Basic256Sha256 Sign, SignAndEncrypt; beyond loopback only SignAndEncrypt starts without ``--insecure``. ``--config
CELL`` serves every robot of a cell file, one MotionDevice each. Prints ``READY opcua=ENDPOINT state=ENDPOINT
robot=HOST:PORT`` (the first robot's) once it serves; runs until SIGINT/SIGTERM. docs/opcua.md.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import signal
import sys
import time
from pathlib import Path
from urllib.parse import urlsplit

from aioadept import defaults
from aioadept.cli.options import ArgumentParser, DefaultsHelpFormatter, add_insecure_option, description

DEFAULT_ENDPOINT = "opc.tcp://127.0.0.1:4840"
STATUS_PERIOD_S = 0.5
"""How often the robot server is asked for ``status`` (an answer at once, even during another client's motion)."""


def build_parser() -> argparse.ArgumentParser:
    from aioadept.opcua.mapping import STALE_AFTER_S, Identity, MotionDeviceCategory

    ident = Identity()
    p = ArgumentParser(prog="aioadept opcua", description=description(__doc__), formatter_class=DefaultsHelpFormatter)
    p.add_argument("--config", metavar="FILE",
                   help="cell file: [opcua] (endpoint, allow_commands, users, stale_after_s, name, and "
                        "[opcua.devices.NAME] identities) and the robots: [robot] or every [[robots]] entry (host, "
                        "port, state_endpoint, model), one MotionDevice each (docs/opcua.md); options given here "
                        "override it")
    p.add_argument("--robot", default=f"{defaults.ROBOT_HOST}:{defaults.ROBOT_PORT}", metavar="HOST[:PORT]",
                   help="the robot server (aioadept sim, or the V+ server): asked for hello and status")
    p.add_argument("--state-endpoint", default=defaults.STATE_ENDPOINT, dest="state_endpoint",
                   help="the robot.state stream to follow (a ZeroMQ endpoint, as aioadept sim --state-endpoint)")
    p.add_argument("--endpoint", default=DEFAULT_ENDPOINT,
                   help="the OPC UA endpoint to serve, opc.tcp://HOST:PORT")
    p.add_argument("--security", default="none", metavar="MODES",
                   help="the security modes offered, comma-separated: none (no signature, no encryption: loopback "
                        "only unless --insecure), sign, sign-and-encrypt (Basic256Sha256)")
    p.add_argument("--certificate", metavar="FILE",
                   help="the server's certificate (DER or PEM) for sign/sign-and-encrypt, with --private-key; none: "
                        "one made self-signed at first start and kept in ~/.local/share/aioadept/opcua")
    p.add_argument("--private-key", metavar="FILE", dest="private_key", help="the certificate's private key (PEM)")
    p.add_argument("--trust", metavar="DIR",
                   help="the trust list: a folder of client application certificates (DER or PEM; a CA's trusts what "
                        "it signed); a client whose certificate it does not hold is refused (BadCertificateUntrusted). "
                        "Only with sign/sign-and-encrypt, none not offered; without it any client certificate is taken")
    add_insecure_option(p)
    p.add_argument("--allow-commands", action="store_true", dest="allow_commands",
                   help="give each robot the methods Stop() and RunSkill(Skill, Arguments) (vendor namespace "
                        "urn:aioadept:opcua:commands), callable by the users of --users only; without it the server "
                        "is read-only")
    p.add_argument("--users", metavar="FILE",
                   help="with --allow-commands: NAME:PASSWORD lines, the users who may call the methods (the file "
                        "must be readable by its owner only)")
    p.add_argument("--user-certificates", metavar="DIR", dest="user_certificates",
                   help="with --allow-commands: a folder of user certificates (DER or PEM, or their CA's): a user who "
                        "presents one (an X509 identity token) may call the methods, named by its common name; only "
                        "with sign/sign-and-encrypt, none not offered")
    p.add_argument("--robot-model", default=None, dest="robot_model", metavar="NAME",
                   help="the arm (aioadept sim --robot-model): its axes (a Cobra's four, J3 linear in mm), and the "
                        "Model and MotionDeviceCategory unless --model/--category say otherwise (none: the Viper "
                        "s850's six axes, Model and category Bad)")
    p.add_argument("--name", default=ident.name, help="the robot's MotionDevice browse name")
    p.add_argument("--manufacturer", default=ident.manufacturer, help="the robot's manufacturer")
    p.add_argument("--model", default="", help="the robot's model, e.g. Viper s850 (none: the variable is Bad)")
    p.add_argument("--category", default=None, choices=[c.name for c in MotionDeviceCategory],
                   help="the robot's MotionDeviceCategory (none: the variable is Bad)")
    p.add_argument("--serial-number", default="", dest="serial_number",
                   help="the robot's serial number (none: the variable is Bad)")
    p.add_argument("--controller-model", default="", dest="controller_model",
                   help="the controller's model, e.g. SmartController EX (none: the variable is Bad)")
    p.add_argument("--stale-after", type=float, default=STALE_AFTER_S, dest="stale_after", metavar="SECONDS",
                   help="a state stream silent this long has stalled: its values turn Uncertain")
    p.add_argument("--log-level", default="WARNING", dest="log_level", help="logging level on stderr")
    return p


def check_endpoint(endpoint: str, insecure: bool, security: tuple[str, ...] = ("none",)) -> str:
    """``endpoint`` if it is ``opc.tcp://HOST:PORT``; ValueError naming it otherwise. Beyond loopback it is refused
    unless every mode of ``security`` encrypts, or ``insecure`` (with SecurityPolicy None a password crosses in clear
    text and anyone on the way may change what is said; signed only, anyone on the way reads it), as every listener
    of the project (:func:`aioadept.cli.options.check_listeners`)."""
    from aioadept.opcua.security import ENCRYPTED

    from aioadept.cli.options import Listener, check_listeners

    parts = urlsplit(endpoint)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme != "opc.tcp" or not parts.hostname or port is None:
        raise ValueError(f"--endpoint {endpoint!r}: expected opc.tcp://HOST:PORT")
    unencrypted = [m for m in security if m != ENCRYPTED]
    check_listeners("aioadept opcua", [Listener(
        "--endpoint", endpoint, authenticated=not unencrypted,
        risk=f"connect with --security {unencrypted[0] if unencrypted else ''} and read what the cell and its users "
             f"say in clear text (offer sign-and-encrypt only)")], insecure)
    return endpoint


async def follow_state(endpoint: str, view, cell) -> None:
    """Each robot.state sample into ``view`` and out to the OPC UA variables at once."""
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.pubsub import Subscriber
    from aioadept.errors import BusError

    log = logging.getLogger("aioadept.opcua")
    bad = 0
    async with Subscriber(endpoint, topics=(ROBOT_STATE_TOPIC,)) as sub:
        async for _topic, payload in sub:
            try:
                state = RobotState.from_bytes(payload)
                view.on_state(state, time.monotonic())
            except (BusError, ValueError) as exc:  # one bad sample is skipped, never fatal; said once
                bad += 1
                if bad == 1:
                    log.warning("skipping a robot.state sample: %s", exc)
                continue
            await cell.refresh(time.monotonic())


async def watch(cell, period_s: float = 0.1) -> None:
    """Refresh on a clock too, so a stream that stopped turns its values Uncertain without a sample to say so."""
    while True:
        await asyncio.sleep(period_s)
        await cell.refresh(time.monotonic())


async def poll_robot(host: str, port: int, view, cell) -> None:
    """``hello`` once per connection and ``status`` every :data:`STATUS_PERIOD_S`; reconnects while the server is
    away (its values turn Uncertain meanwhile)."""
    from aioadept.client import RobotClient
    from aioadept.errors import AdeptError

    log = logging.getLogger("aioadept.opcua")
    while True:
        try:
            async with RobotClient(host, port, connect_timeout_s=2.0, ack_timeout_s=2.0) as robot:
                view.on_hello(await robot.hello())
                while True:
                    view.on_status(await robot.status(), time.time())
                    await cell.refresh(time.monotonic())
                    await asyncio.sleep(STATUS_PERIOD_S)
        except (AdeptError, OSError, TimeoutError) as exc:
            log.info("robot server %s:%d: %s", host, port, exc)
            view.on_status(None)
            view.on_hello(None)
            await cell.refresh(time.monotonic())
            await asyncio.sleep(1.0)


ROBOT_OPTIONS = ("robot", "state_endpoint", "robot_model", "name", "manufacturer", "model", "category",
                 "serial_number", "controller_model")
"""The options that describe the one robot of the command line (with ``[[robots]]`` each entry says its own)."""


def _given(parser: argparse.ArgumentParser, args: argparse.Namespace) -> set[str]:
    """The options whose value is not their default (given on the command line)."""
    return {k for k, v in vars(args).items() if v != parser.get_default(k)}


def identity_of(args: argparse.Namespace, given: set[str], base=None):
    """The one robot's identity: ``base`` (the cell file's, or none) with the options given; ``--robot-model`` names
    the axes, and the Model and category unless ``--model``/``--category`` do."""
    import dataclasses

    from aioadept.opcua.mapping import MotionDeviceCategory, identity_of_model

    said = {k: getattr(args, k) for k in ("name", "manufacturer", "model", "serial_number", "controller_model")
            if base is None or k in given}
    if args.category is not None:
        said["category"] = MotionDeviceCategory[args.category]
    if base is None:
        if args.robot_model is None:  # the sim's arm, but no Model or category the cell did not say
            said.setdefault("category", None)
        elif not args.model:
            del said["model"]  # the model's own
        return identity_of_model(args.robot_model or "viper-s850", **said)
    if "robot_model" in given:
        fresh = identity_of_model(args.robot_model, name=base.name)
        base = dataclasses.replace(base, axes=fresh.axes, linear=fresh.linear, axis_names=fresh.axis_names,
                                   model=fresh.model, category=fresh.category)
    return dataclasses.replace(base, **said)


def robot_plans(parser: argparse.ArgumentParser, args: argparse.Namespace) -> list:
    """The robots to serve, from the options or the cell file (``--config``, whose ``[opcua]`` settings go into
    ``args`` unless given on the command line). ValueError (one line naming the option, or the file and key)."""
    from aioadept.cli.options import parse_robot_address
    from aioadept.opcua.config import RobotPlan, load_plan

    given = _given(parser, args)
    if not args.config:
        host, port = parse_robot_address(args.robot, defaults.ROBOT_PORT)
        return [RobotPlan(host, port, args.state_endpoint, identity_of(args, given))]
    cell = load_plan(args.config)
    o = cell.opcua
    for opt, value in (("endpoint", o.endpoint), ("users", o.users or None), ("stale_after", o.stale_after_s),
                       ("security", ",".join(o.security)), ("certificate", o.certificate or None),
                       ("private_key", o.private_key or None), ("trust", o.trust or None),
                       ("user_certificates", o.user_certificates or None)):
        if opt not in given:
            setattr(args, opt, value)
    args.allow_commands = args.allow_commands or o.allow_commands
    if cell.many:
        mine = [k for k in ROBOT_OPTIONS if k in given]
        if mine:
            raise ValueError(f"--{mine[0].replace('_', '-')}: {args.config} has [[robots]]: each robot's entry says "
                             f"its own")
        return list(cell.robots)
    r = cell.robots[0]
    host, port = parse_robot_address(args.robot, defaults.ROBOT_PORT) if "robot" in given else (r.host, r.port)
    state = args.state_endpoint if "state_endpoint" in given else r.state_endpoint
    return [RobotPlan(host, port, state, identity_of(args, given, r.identity))]


async def run(args: argparse.Namespace, robots: list, users: dict[str, str] | None,
              security: tuple[str, ...] = ("none",)) -> int:
    from aioadept.errors import AdeptError
    from aioadept.opcua.commands import RobotCommands
    from aioadept.opcua.mapping import RobotView
    from aioadept.opcua.server import CellServer

    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    views = [RobotView(r.identity, stale_after_s=args.stale_after) for r in robots]
    commands = [RobotCommands(r.host, r.port) for r in robots] if args.allow_commands else None
    cell = CellServer(args.endpoint, views, commands=commands, users=users, security=security,
                      certificate=args.certificate and Path(args.certificate),
                      private_key=args.private_key and Path(args.private_key), trust=args.trust and Path(args.trust),
                      user_certificates=args.user_certificates and Path(args.user_certificates))
    tasks: list[asyncio.Task] = []
    stopping_since: float | None = None
    try:
        await cell.start()
        for c in commands or ():
            try:
                await c.connect()
            except (AdeptError, OSError) as exc:  # the methods connect when called; said here once
                logging.getLogger("aioadept.opcua").warning("commands: robot server not reachable yet: %s", exc)
        tasks = [asyncio.create_task(watch(cell), name="opcua-watch")]
        for r, view in zip(robots, views, strict=True):
            tasks += [asyncio.create_task(follow_state(r.state_endpoint, view, cell), name=f"opcua-state-{r.name}"),
                      asyncio.create_task(poll_robot(r.host, r.port, view, cell), name=f"opcua-robot-{r.name}")]
        first = robots[0]
        print(f"READY opcua={args.endpoint} state={first.state_endpoint} robot={first.host}:{first.port}"
              + (f" robots={len(robots)}" if len(robots) > 1 else ""), flush=True)
        stopped = asyncio.create_task(stop.wait())
        done, _ = await asyncio.wait({*tasks, stopped}, return_when=asyncio.FIRST_COMPLETED)
        stopped.cancel()
        if stop.is_set():
            stopping_since = time.monotonic()
        for t in done:
            if t is not stopped and not t.cancelled() and t.exception() is not None:
                raise t.exception()  # type: ignore[misc]
    finally:
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        closed = await cell.stop()
        for c in commands or ():
            await c.close()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
    if stopping_since is not None:
        print(f"aioadept opcua: stopped in {time.monotonic() - stopping_since:.2f} s, {closed} client connection(s) "
              f"closed", file=sys.stderr, flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    from aioadept.cli.options import run_node, setup_logging
    from aioadept.cell.schema import report

    parser = build_parser()
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
    # asyncua says much about the nodesets it imports, and logs a failed bind with its traceback before raising
    # it (said here in one line): its own log only with --log-level DEBUG.
    debug = logging.getLogger().level <= logging.DEBUG
    logging.getLogger("asyncua").setLevel(logging.DEBUG if debug else logging.CRITICAL)
    try:
        robots = robot_plans(parser, args)
        from aioadept.opcua.security import check_modes

        security = check_modes(args.security.split(","))
        check_endpoint(args.endpoint, args.insecure, security)
        if (args.certificate is None) != (args.private_key is None):
            raise ValueError("--certificate and --private-key go together (neither: one made at first start)")
        if security == ("none",) and args.certificate:
            raise ValueError("--certificate: only for --security sign or sign-and-encrypt")
        for option, path in (("--certificate", args.certificate), ("--private-key", args.private_key)):
            if path and not Path(path).is_file():
                raise ValueError(f"{option} {path}: no such file")
        if not args.stale_after > 0:
            raise ValueError(f"--stale-after {args.stale_after!r}: expected seconds > 0")
        if args.allow_commands != bool(args.users or args.user_certificates):
            raise ValueError("--allow-commands needs --users FILE or --user-certificates DIR (who may command), and "
                             "--users is only for --allow-commands")
        for option, folder in (("--trust", args.trust), ("--user-certificates", args.user_certificates)):
            if folder and "none" in security:
                raise ValueError(f"{option}: only with --security sign or sign-and-encrypt, none not offered (a "
                                 f"client that picks none skips it)")
            if folder:
                from aioadept.opcua.security import check_trust_folder

                check_trust_folder(Path(folder), option)
        users = None
        if args.users:
            from aioadept.opcua.commands import read_users

            users = read_users(args.users)
    except (ValueError, OSError) as exc:   # one line naming the option or the file, no usage block
        return report("aioadept opcua", exc)
    code = run_node("aioadept opcua", run(args, robots, users, security))
    # Everything is closed by now. The address space is over half a million Python objects, and the interpreter's
    # exit freed them one by one: 1.5-2 s on an idle machine, past a supervisor's 5 s grace under load.
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
