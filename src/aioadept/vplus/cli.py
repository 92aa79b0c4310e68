"""``aioadept sim --vplus FILE... --run PROGRAM``: the emulated controller running V+ code, in real time.

The files are loaded (problems are printed on stderr with file:line), PROGRAM runs in task 0, TYPE output and
task messages go to stdout as ``[task] text`` lines. Each ``FOPEN /LOCAL_PORT n`` binds ``--host`` on port n, or on
the port that ``--map-port n=m`` gives (m = 0: an ephemeral port), and prints
``READY host=H port=P vport=n state=none``, the line ``aioadept.testing.running_node`` waits for.
The robot is the Python sim's Controller (same kinematics, motion timing, --time-scale, --monitor-speed); the
ZeroMQ state stream (``--state-endpoint``, ``--state-rate-hz``, CURVE) and ``--fault`` work as with the Python
backend (the READY line names the stream's endpoint).
"""

from __future__ import annotations

import argparse
import asyncio
import errno
import signal
import sys
import time
from pathlib import Path
from typing import Any

from aioadept.errors import one_line
from aioadept.sim.server import REST_WAIT_S


def parse_port_map(specs: list[str]) -> dict[int, int]:
    """``["1234=0", "5000=15000"]`` -> ``{1234: 0, 5000: 15000}``; raises ``ValueError``."""
    out: dict[int, int] = {}
    for spec in specs:
        try:
            v, h = spec.split("=", 1)
            vport, hport = int(v), int(h)
        except ValueError:
            raise ValueError(f"--map-port expects VPORT=HOSTPORT, got {spec!r}") from None
        if not (0 < vport < 65536 and 0 <= hport < 65536):
            raise ValueError(f"--map-port {spec!r}: port out of range")
        out[vport] = hport
    return out


async def run(args: argparse.Namespace, options: Any) -> int:
    """Serve until SIGINT/SIGTERM. ``options`` (:class:`aioadept.sim.server.SimOptions`, from the same command
    line: ``aioadept.cli.sim.options_from_args``) gives the robot, the state stream and the faults exactly as for
    the Python backend."""
    from aioadept.vplus.iodev import Network

    port_map = parse_port_map(args.map_port)
    ctl = options.make_controller()
    made = _make_emulator(args, ctl)
    if made is None:
        return 2
    emu, clock, wall0 = made
    from aioadept.vplus import linehits

    lines = linehits.from_env(emu.rt)     # AIOADEPT_VPLUS_LINES: the lines run, for a test suite's report
    debug_server = await _debug_port(args, emu)
    if debug_server is False:
        return 2

    publisher = None
    state = "none"
    if options.state_endpoint is not None:
        from aioadept.bus.pubsub import Publisher

        publisher = Publisher(options.state_endpoint, bind=True, curve=options.state_curve)
        state = publisher.actual_endpoint

    stop = asyncio.Event()
    sup = Supervisor(emu, args.run, stop)

    def on_listen(vport: int, host: str, port: int) -> None:
        from aioadept.bus.zenoh import announce_ready

        sup.listening = True
        announce_ready()  # --transport zenoh: the node's liveliness token (no-op on ZeroMQ)
        print(f"READY host={host} port={port} vport={vport} state={state}", flush=True)

    def on_bind_error(vport: int, host: str, port: int, exc: OSError) -> None:
        # The program has its IOSTAT error, as on a controller, but this host serves the ports of its command line:
        # one it cannot bind ends the run (the Python sim's rule), rather than a server that looks alive
        why = "already in use" if exc.errno == errno.EADDRINUSE else one_line(exc)
        sup.die(f"V+ port {vport} ({host}:{port}) cannot be bound: {why} (--map-port {vport}=0 binds a free port)")

    emu.rt.devices = Network(args.host, port_map, on_listen, faults=options.faults, on_bind_error=on_bind_error,
                             send_buffer=getattr(args, "tcp_send_buffer", None))
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    states = None if publisher is None else _stream_states(publisher, ctl, clock, wall0, options)
    emu.rt.on_task_end = sup.on_task_end
    emu.rt.on_task_pause = sup.on_task_pause
    loop.set_exception_handler(sup.on_loop_error)
    try:
        emu.execute(0, args.run)
        await emu.serve(stop)
    except Exception as exc:  # noqa: BLE001 - an emulator bug outside any task: one line, not a traceback
        sup.die(f"emulator internal error {one_line(exc)}; every V+ task was aborted")
    finally:
        sup.closing = True
        if debug_server is not None:
            debug_server.close()
        await _shut_down(emu, ctl, clock, states, publisher, options)
        linehits.save(lines)
    return sup.status


async def _debug_port(args: argparse.Namespace, emu: Any) -> Any:
    """``--debug-port PORT``: the emulator runs its instrumented form under a debugger, and DAP ``attach``
    sessions are served on 127.0.0.1:PORT (aioadept.vplus.dap; ``DEBUG host=127.0.0.1 port=P`` on stdout). The
    server, None without the option, False (one line on stderr) when the port cannot be bound."""
    port = getattr(args, "debug_port", None)
    if port is None:
        return None
    from aioadept.vplus import dap
    from aioadept.vplus.debugger import Debugger

    try:
        server = await dap.serve_attach(emu, Debugger(emu.rt), "127.0.0.1", port)
    except (OSError, OverflowError) as exc:
        print(f"aioadept sim: --debug-port {port}: {getattr(exc, 'strerror', None) or exc}", file=sys.stderr, flush=True)
        return False
    print(f"DEBUG host=127.0.0.1 port={server.sockets[0].getsockname()[1]}", flush=True)
    return server


def _make_emulator(args: argparse.Namespace, ctl: Any) -> tuple[Any, Any, float] | None:
    """Load ``--vplus`` (problems on stderr) into an emulator on a real clock driving ``ctl``: (emulator, clock,
    the wall time of clock 0), or None (one line on stderr) when ``--run`` names no loaded program."""
    from aioadept.vplus import Emulator, RealClock
    from aioadept.vplus.loader import load_files
    from aioadept.vplus.parse import norm
    from aioadept.vplus.robot import RobotDevice

    def console(task: int, text: str) -> None:
        print(f"[{task}] {text}", flush=True)

    try:
        module = load_files(args.vplus)
    except OSError as exc:
        print(f"aioadept sim: --vplus {exc.filename}: {exc.strerror or exc}", file=sys.stderr, flush=True)
        return None
    for path in args.vplus:
        if not any(prog.file == Path(path).name for prog in module.programs.values()):
            print(f"aioadept sim: --vplus {path}: no .PROGRAM in it; is it a V+ module?", file=sys.stderr,
                  flush=True)
            return None
    clock = RealClock()
    wall0 = time.time() - clock.now
    emu = Emulator(module, robot=RobotDevice(ctl), clock=clock, console=console, cycle_s=args.vplus_cycle,
                   disk_dir=getattr(args, "disk", None))
    if emu.problems:
        _print_problems(emu.problems, args)
        if getattr(args, "strict", False):
            return None
    if norm(args.run) not in module.programs:
        print(f"aioadept sim: --run {args.run}: no such program in {', '.join(args.vplus)}", file=sys.stderr,
              flush=True)
        return None
    return emu, clock, wall0


_SHOWN_PROBLEMS = 20


def _print_problems(problems: list[Any], args: argparse.Namespace) -> None:
    """The first lines that did not load, then one line saying how many and what it means (the last word before
    READY, so that it is not missed above the program's own output)."""
    for p in problems[:_SHOWN_PROBLEMS]:
        print(f"aioadept sim: {p}", file=sys.stderr, flush=True)
    more = len(problems) - _SHOWN_PROBLEMS
    files = " ".join(args.vplus)
    head = f"... and {more} more; " if more > 0 else ""
    then = ("--strict: not serving" if getattr(args, "strict", False)
            else "their programs do not run; --strict refuses to serve")
    print(f"aioadept sim: {head}{len(problems)} line(s) did not load ({then}); `aioadept vplus check {files}` "
          "lists every one", file=sys.stderr, flush=True)


def _stream_states(publisher: Any, ctl: Any, clock: Any, wall0: float, options: Any) -> asyncio.Future:
    """The state stream's task: samples of the arm (and the world, if any) at the emulator's clock, which is the
    controller's time."""
    from aioadept.sim.server import publish_robot_states, robot_state_sample, world_state_sample

    io_cursor = [0]  # each signal change goes out once, in the sample after it
    world_cursor = [0]  # each world event too
    world_sample = None if ctl.world is None else (lambda: world_state_sample(ctl, clock.now, wall0, world_cursor))
    return asyncio.ensure_future(publish_robot_states(
        publisher, lambda: robot_state_sample(ctl, clock.now, wall0, io_cursor), options.state_rate_hz,
        world_sample=world_sample))


async def _shut_down(emu: Any, ctl: Any, clock: Any, states: asyncio.Future | None, publisher: Any,
                     options: Any) -> None:
    """Close every connection, abort every task, let the stream show the arm at rest, then end it."""
    from aioadept.vplus import iodev

    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.remove_signal_handler(sig)
    iodev.close_all(emu.rt)
    for n in list(emu.rt.tasks):
        emu.rt.abort(n)
    if states is not None:
        # the stream shows the braked arm come to rest before it ends (bounded: a stop takes well under this)
        t_end = loop.time() + REST_WAIT_S
        while ctl.trajectory.in_motion(clock.now) and loop.time() < t_end:
            await asyncio.sleep(0.01)
        await asyncio.sleep(2.0 / options.state_rate_hz)
        states.cancel()
        await asyncio.gather(states, return_exceptions=True)
    if publisher is not None:
        publisher.close()
    loop.set_exception_handler(None)


GRACE_S = 0.5
"""After READY, how long the other tasks may run on after one task ended without an error before the server
counts as dead. ``rs.halt`` ends both of the shipped server's loops within one ``rs.poll`` (16 ms)."""


class Supervisor:
    """Never a server that only looks alive: decides, each time a V+ task stops, whether the program has died.

    - A task stops with an error (any task, any time): the server is dead. So is a task that PAUSEs: nothing
      here can PROCEED it.
    - Before READY, the ``--run`` program's tasks may end (a launcher that EXECUTEs others); when none is left,
      the program ended before it opened a socket.
    - After READY, a task that ends without an error while others run on (HALT in a skill, a loop that
      returned) is dead too unless every task has ended within :data:`GRACE_S` (a clean ``rs.halt``): a reader
      without its executor queues commands nobody runs, an executor without its reader serves nobody.
    - A Python exception outside the tasks (the scheduler, an I/O callback): dead.

    Death: the arm is braked at once, ``stop`` is set (``run`` then closes every connection and aborts every
    task), stderr gets one line saying which task and program died, where and why, and the exit status is 1.
    Every task ended after READY: one line, exit status 0.
    """

    def __init__(self, emu: Any, run: str, stop: asyncio.Event) -> None:
        self.emu = emu
        self.run = run
        self.stop = stop
        self.listening = False
        self.closing = False          # the shutdown's own aborts are no death
        self.status = 0
        self.why: str | None = None

    def on_task_end(self, T: Any) -> None:
        if self.closing or self.why is not None:
            return
        rt = self.emu.rt
        if T.state == "error":
            if T.num == 0 and not self.listening:
                self.die(f"{self.run} stopped before it opened a socket: {_explain(T.error)}")
            else:
                self.die(f"V+ task {T.num} ({T.program}) stopped: {_explain(T.error)}")
            return
        if not any(t is not T and t.state == "running" for t in rt.tasks.values()):
            if not self.listening:
                self.die(f"{self.run} ended before it opened a socket (no V+ task is running)")
            else:
                self.why = "every V+ task has ended"
                print(f"aioadept sim: {self.why}", file=sys.stderr, flush=True)
                self.stop.set()
            return
        if self.listening:
            if T.robot_attached:
                self._brake()     # the arm's program has ended: whatever comes next, no motion goes on
            asyncio.get_running_loop().call_later(GRACE_S, self._after_grace, T)

    def on_task_pause(self, T: Any) -> None:
        """PAUSE: only PROCEED would resume the task, and nothing here can give it: as good as HALT."""
        if self.closing or self.why is not None:
            return
        how = f"paused by PAUSE at {_where(*T.halted_at)} (nothing can PROCEED it here)"
        if T.num == 0 and not self.listening:
            self.die(f"{self.run} stopped before it opened a socket: {how}")
        else:
            self.die(f"V+ task {T.num} ({T.program}) {how}: the server cannot serve")

    def _after_grace(self, T: Any) -> None:
        rt = self.emu.rt
        if self.closing or self.why is not None or rt.tasks.get(T.num) is not T:
            return                # already decided, or the task was started again
        others = [t for t in rt.tasks.values() if t.state == "running"]
        if not others:
            return                # the last task's end has decided
        how = "was aborted" if T.state == "aborted" else "ended"
        if T.halted_at is not None:
            how = f"halted by HALT at {_where(*T.halted_at)}"
            if T.trapped is not None and T.halted_at[1].lower() == T.trapped[0].lower():
                how += f" (its error trap, called for {_explain(T.trapped[1])})"
        runs = ", ".join(f"task {t.num} ({t.program})" for t in others)
        self.die(f"V+ task {T.num} ({T.program}) {how} while {runs} ran on: the server cannot serve")

    def on_loop_error(self, loop: asyncio.AbstractEventLoop, context: dict) -> None:
        """asyncio's exception handler: an exception in an I/O callback of the emulator is its death. (A peer's
        socket error is no exception here: asyncio reports OSError on a transport only in debug mode.)"""
        exc = context.get("exception")
        if exc is None or isinstance(exc, (OSError, asyncio.CancelledError)) or self.closing:
            loop.default_exception_handler(context)
            return
        self.die(f"emulator internal error {one_line(exc)} ({context.get('message', 'in a callback')}); "
                 f"every V+ task was aborted")

    def die(self, why: str) -> None:
        if self.why is not None:
            return
        self._brake()
        self.why = why
        self.status = 1
        print(f"aioadept sim: {why}", file=sys.stderr, flush=True)
        self.stop.set()

    def _brake(self) -> None:
        robot = self.emu.rt.robot
        if robot is not None:
            robot.brake(self.emu.rt.now)


def _where(file: str | None, program: str | None, line: int | None) -> str:
    """``rsconfig.V2:85 in crash.trap``, or what of it is known."""
    if file and line:
        return f"{file}:{line} in {program}" if program else f"{file}:{line}"
    if program:
        return f"{program}, line {line}" if line else program
    return "an unknown place"


def _explain(err: Any) -> str:
    """A task's error and where (``*Division by 0* at rsconfig.V2:85 in crash.trap``), and for an undefined
    program the likely cause: its module was not loaded. (V+ reports an undefined program only when the CALL
    executes, so a program the run never reaches is not an error: the shipped server calls rs.state only with the
    state stream on.)"""
    from aioadept.vplus import errors as E

    if getattr(err, "program", None) is not None:
        text = f"{err.message} at {_where(err.file, err.program, err.line)}"
    else:
        text = str(err)
    if getattr(err, "code", None) == E.UNDEFINED_PROGRAM:
        name = str(err.message).replace(E.text(E.UNDEFINED_PROGRAM), "").strip()
        text += f": no loaded file defines {name} (load its module too)"
    return text
