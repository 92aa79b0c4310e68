"""``aioadept send``: send skill calls to a robot server from the shell and print one line per ack.

    aioadept send --robot 127.0.0.1:1234 "move_to:300,0,500,0,180,0" break
    aioadept send --joined "set_speed:20" "move_rel_tool:0,0,2.5,0,0,0" break
    aioadept send --json here

``--robot HOST[:PORT]`` names the server as every client subcommand does; ``--host``/``--port`` say the same in two
options. Each argument is ``SKILL[:ARG,ARG,...]`` (the wire syntax without the ID); integers stay integers (``set_speed:20``).
By default each skill is its own command, awaited before the next is sent (``cmdexec``); ``--joined`` writes them
all at once (``cmdexec_joined``). Exit status: 0 all done, 1 an ``error``/``aborted`` ack, 2 bad usage,
3 connection failure (also: the peer did not answer ``hello`` like a RobotServer within 2 s; ``--no-hello``
for the original V+ AdeptServer) or ack timeout, 130 interrupted (Ctrl-C: ``stop`` was sent at once, no further command, and the
stop was acked; 3 if it was not). A second Ctrl-C exits at once.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from collections.abc import AsyncIterator, Sequence

from aioadept import defaults
from aioadept.apps.interrupt import Interrupter, run_interruptible
from aioadept.client import ExecResult, MessageResult, RobotClient
from aioadept.commands import Skill
from aioadept.errors import AckTimeout, CommandAborted, CommandError, ConnectError, ConnectionLost
from aioadept.cli.options import ArgumentParser, add_robot_option, description, parse_robot_address
from aioadept.protocol import STOP_SKILL


def parse_skill(text: str) -> Skill:
    """``"move_to:1,2,3,4,5,6"`` -> ``Skill("move_to", 1, 2, 3, 4, 5, 6)``; ValueError naming what is wrong."""
    name, sep, rest = text.partition(":")
    args: list[int | float] = []
    if sep:
        for i, tok in enumerate(rest.split(",")):
            tok = tok.strip()
            try:
                args.append(int(tok))
            except ValueError:
                try:
                    args.append(float(tok))
                except ValueError:
                    raise ValueError(f"{text!r}: argument {i} ({tok!r}) is not a number") from None
    return Skill(name, *args)


def _line(r: MessageResult) -> str:
    a = r.ack
    pose = ",".join("%.3f" % v for v in a.pose.as_tuple())
    extra = (" " + ":".join(a.extra)) if a.extra else ""
    return (f"{r.id} {r.skill:<15} {a.status.value:<7} t={a.t_start_s:.3f}..{a.t_done_s:.3f} pose={pose} "
            f"rtt={r.rtt_s * 1e3:.2f}ms{extra}")


def _record(r: MessageResult) -> dict:
    a = r.ack
    return {"id": r.id, "skill": r.skill, "args": list(r.args), "status": a.status.value,
            "t_start_s": a.t_start_s, "t_done_s": a.t_done_s, "pose": list(a.pose.as_tuple()),
            "extra": list(a.extra), "t_send_s": r.t_send_s, "t_recv_s": r.t_recv_s, "batch": r.batch}


def _print(results: Sequence[MessageResult], as_json: bool) -> None:
    for r in results:
        print(json.dumps(_record(r)) if as_json else _line(r), flush=True)


async def _run(args: argparse.Namespace, commands: list[Skill], intr: Interrupter | None = None) -> int:
    try:
        robot = RobotClient(args.host, args.port, connect_timeout_s=args.connect_timeout,
                            ack_timeout_s=args.timeout, hello_timeout_s=None if args.no_hello else 2.0,
                            stop_port=_stop_port(args.stop_port))
    except ValueError as exc:  # a timeout that is not finite and > 0, a port out of range
        print(f"aioadept send: {exc}", file=sys.stderr)
        return 2
    try:
        async with robot, (intr.guard(robot) if intr is not None else _nothing()):
            try:
                res: ExecResult = await (robot.cmdexec_joined(*commands) if args.joined
                                         else robot.cmdexec(*commands))
            except (CommandError, CommandAborted) as exc:
                done = getattr(exc, "completed", None)
                _print(done.messages if done is not None else (), args.json)
                _print(getattr(exc, "results", ()), args.json)
                print(f"aioadept send: {exc}", file=sys.stderr)
                return 1
            _print(res.messages, args.json)
            return 0
    except (ConnectError, ConnectionLost, AckTimeout) as exc:
        if [k.skill for c in commands for k in c.calls()] == [STOP_SKILL] and robot.stop_port is not None:
            # `send stop` that cannot get in (every client slot taken, a dead link): the stop port
            try:
                _print([await robot.stop_on_stop_port(timeout_s=args.timeout)], args.json)
                return 0
            except (ConnectError, AckTimeout, CommandError, CommandAborted) as side:
                exc = ConnectError(f"{exc}; on the stop port: {side}")
        print(f"aioadept send: {exc}", file=sys.stderr)
        return 3


def robot_address(args: argparse.Namespace) -> tuple[str, int]:
    """The server's ``(host, port)``: ``--robot``, or ``--host``/``--port``, never both; the defaults otherwise."""
    if args.robot is not None:
        if args.host is not None or args.port is not None:
            raise ValueError("--robot names the server: give it, or --host/--port, not both")
        return parse_robot_address(args.robot)
    return (args.host if args.host is not None else defaults.ROBOT_HOST,
            args.port if args.port is not None else defaults.ROBOT_PORT)


def _stop_port(text: str) -> int | str | None:
    if text.lower() in ("auto", "none"):
        return text.lower() if text.lower() == "auto" else None
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"--stop-port: {text!r} is not a port number, 'auto' or 'none'") from None


@contextlib.asynccontextmanager
async def _nothing() -> AsyncIterator[None]:
    yield None


def _is_number(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _syntax_hint(tokens: Sequence[str]) -> str:
    """The expected form of the arguments, with the user's own words rewritten into it when they look like
    ``move_to 300 0 500 ...`` (arguments given as separate words)."""
    fixed: list[str] = []
    for tok in tokens:
        if _is_number(tok) and fixed:
            fixed[-1] += ("," if ":" in fixed[-1] else ":") + tok
        else:
            fixed.append(tok)
    if fixed != list(tokens):
        return (f"each argument is SKILL[:ARG,ARG,...], one word per skill: did you mean "
                f"'aioadept send {' '.join(fixed)}'?")
    return ("each argument is SKILL[:ARG,ARG,...], one word per skill, e.g. "
            "'aioadept send move_to:300,0,500,0,180,0 break'")


def build_parser() -> argparse.ArgumentParser:
    ap = ArgumentParser(prog="aioadept send", description=description(__doc__))
    ap.add_argument("skills", nargs="+", metavar="SKILL[:ARGS]", help="skill calls, e.g. move_to:1,2,3,4,5,6")
    add_robot_option(ap)
    ap.add_argument("--host", default=None, help=f"robot server address, as --robot HOST (default {defaults.ROBOT_HOST})")
    ap.add_argument("--port", type=int, default=None, help=f"robot server port, as --robot :PORT (default {defaults.ROBOT_PORT})")
    ap.add_argument("--joined", action="store_true", help="write all messages at once (cmdexec_joined)")
    ap.add_argument("--timeout", type=float, default=60.0, help="ack timeout per wait, seconds (default 60)")
    ap.add_argument("--stop-port", default="auto", dest="stop_port", metavar="PORT",
                    help="the server's stop port, used for 'send stop' when the connection cannot be made "
                         "('auto': the server's port + 1; 'none')")
    ap.add_argument("--connect-timeout", type=float, default=5.0, help="connect timeout, seconds (default 5)")
    ap.add_argument("--json", action="store_true", help="print one JSON object per ack")
    ap.add_argument("--no-hello", action="store_true", dest="no_hello",
                    help="do not check with 'hello' that the peer is a RobotServer (needed for the original V+ "
                         "AdeptServer, which halts on skills it does not know)")
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(list(sys.argv[1:] if argv is None else argv))
    try:
        args.host, args.port = robot_address(args)
    except ValueError as exc:
        ap.error(str(exc))
    try:
        commands = [parse_skill(s) for s in args.skills]
    except ValueError as exc:
        print(f"aioadept send: {exc}; {_syntax_hint(args.skills)}", file=sys.stderr)
        return 2

    async def app(intr: Interrupter) -> int:
        return await _run(args, commands, intr)

    return run_interruptible(app, prog="aioadept send", stop_timeout_s=args.timeout, stop_failed_code=3)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
