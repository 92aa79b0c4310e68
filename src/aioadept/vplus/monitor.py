"""``aioadept vplus monitor``: the V+ monitor over the emulator, in real time, with the simulated arm.

The commands a user types at a controller's terminal (docs/vplus.md, "Debugging": the table, with what is
UNCONFIRMED), on the debugger's core (:mod:`aioadept.vplus.debugger`): ``BPT`` sets its breakpoints, ``PROCEED``,
``SSTEP`` and ``XSTEP`` resume and step a task stopped at one. :class:`Monitor` does one command line at a time
(text in, text out); :func:`serve` reads lines with line editing and history (``readline``) while the tasks run.
"""

from __future__ import annotations

import asyncio
import re
import sys
from collections.abc import Callable
from typing import Any

from aioadept.errors import AdeptError
from aioadept.vplus.debugger import DebugError, Debugger, render
from aioadept.vplus.parse import norm

PROMPT = ". "
UNKNOWN = "*Unknown command*"
"""The reply to a line that is no monitor command (UNCONFIRMED: V+'s exact text)."""
NOT_HERE = ("RETRY", "ZERO", "STORE", "DELETE", "DELETEP", "EDIT", "SEE", "COPY", "RENAME", "FLIST", "CALIBRATE",
            "ENABLE", "DISABLE", "TESTP", "TOOL", "ESTOP", "SWITCH", "PARAMETER", "PRIME", "CYCLE.END", "SRV.RESET")
"""V+ monitor commands this monitor does not have: each gets one line saying so."""


class MonitorError(AdeptError):
    """A command that cannot be done: its text is the reply."""


class Monitor:
    """The monitor's state: the loaded files, the emulator and its debugger; :meth:`command` runs one line."""

    def __init__(self, make_emulator: Callable[[list[str]], Any], out: Callable[[str], None]) -> None:
        self._make = make_emulator
        self.out = out
        self.files: list[str] = []
        self.emu: Any = None
        self.debugger: Debugger | None = None
        self.bpts: dict[tuple[str, int], int] = {}       # (program, step) -> file line
        self.on_new_emulator: Callable[[Any], None] = lambda emu: None
        self.remote = False                                # attached to a running sim's emulator

    def attach(self, emu: Any, debugger: Debugger) -> None:
        """Work on the emulator of a running ``aioadept sim --vplus --debug-port`` (no LOAD)."""
        self.emu, self.debugger, self.remote = emu, debugger, True
        debugger.on_event = self._event

    # -- commands ------------------------------------------------------------------------------------------------
    def command(self, line: str) -> str:
        """Run one monitor command line; the reply (may be empty)."""
        line = line.strip()
        if not line:
            return ""
        word, _, rest = line.partition(" ")
        word = word.upper()
        if "/" in word:
            word, _, sw = word.partition("/")
            rest = "/" + sw + " " + rest
        method = getattr(self, "cmd_" + word.replace(".", "_"), None)
        if method is None:
            if word in NOT_HERE:
                return f"{word}: a V+ monitor command this monitor does not have"
            return UNKNOWN
        try:
            return method(rest.strip())
        except (MonitorError, DebugError) as exc:
            return str(exc)

    def cmd_LOAD(self, rest: str) -> str:
        if self.remote:
            raise MonitorError("LOAD: not over --connect (the sim has loaded its files)")
        if not rest:
            raise MonitorError("*Missing argument* LOAD file")
        if self.emu is not None and self.emu.rt.active():
            raise MonitorError("*Task already active*: ABORT the running tasks before LOAD (this monitor loads "
                               "the files again into a new emulator)")
        files = [*self.files, rest]
        try:
            emu = self._make(files)
        except OSError as exc:
            raise MonitorError(f"*Nonexistent file* {rest}: {exc.strerror or exc}") from None
        problems = [str(p) for p in emu.problems if p.file == _base(rest)]
        self.files = files
        self._use(emu)
        names = sorted(p.name for p in emu.rt.module.programs.values() if p.file == _base(rest))
        return "\n".join([*problems, *(f".PROGRAM {n}()" for n in names)])

    def _use(self, emu: Any) -> None:
        old = self.emu
        if old is not None:
            old.rt.robot = None               # the arm belongs to the new emulator
        self.emu = emu
        self.debugger = Debugger(emu.rt, self._event)
        for (prog, step), _ in list(self.bpts.items()):
            self._set_bpt(prog, step)
        self.on_new_emulator(emu)

    def _event(self, name: str, body: dict) -> None:
        if name == "stopped":
            T = self.emu.rt.tasks.get(body["threadId"])
            frames = T.frames if T is not None and T.frames else []
            where = f"{frames[0].program}, step {self._step(frames[0])}" if frames else "?"
            why = {"breakpoint": "Break at", "step": "Step at", "exception": "Error at"}.get(body["reason"], "At")
            self.out(f"({body['threadId']}) {why} {where}" + (f": {body['text']}" if body.get("text") else ""))
        elif name == "output":
            self.out(body["output"].rstrip("\n"))

    def _need(self) -> tuple[Any, Debugger]:
        if self.emu is None or self.debugger is None:
            raise MonitorError("*Undefined program*: nothing is loaded (LOAD file)")
        return self.emu, self.debugger

    def cmd_EXECUTE(self, rest: str) -> str:
        emu, _ = self._need()
        m = re.match(r"(?:/C\s*)?(?:(\d+)\s+)?([A-Za-z][\w.]*)\s*(?:\((.*)\))?\s*(?:,\s*(-?\d+))?\s*\Z", rest, re.I)
        if m is None:
            raise MonitorError("*Invalid format* EXECUTE [task] program[(args)][, cycles]")
        task, prog, args, cycles = int(m.group(1) or 0), norm(m.group(2)), m.group(3), int(m.group(4) or 1)
        if prog not in emu.rt.module.programs:
            raise MonitorError(f"*Undefined program* {prog}")
        values = [self.debugger.evaluate(a, None) for a in _split_args(args)] if args else []
        try:
            emu.execute(task, prog, *values, cycles=cycles)
        except Exception as exc:  # noqa: BLE001 - a V+ error starting the task: its text
            raise MonitorError(str(exc)) from None
        return ""

    def _task_arg(self, rest: str) -> int:
        try:
            return int(rest or 0)
        except ValueError:
            raise MonitorError(f"*Invalid task number* {rest}") from None

    def cmd_ABORT(self, rest: str) -> str:
        emu, _ = self._need()
        emu.abort(self._task_arg(rest))
        return ""

    def cmd_KILL(self, rest: str) -> str:
        emu, _ = self._need()
        emu.rt.kill(self._task_arg(rest))
        return ""

    def cmd_PROCEED(self, rest: str) -> str:
        emu, dbg = self._need()
        num = self._task_arg(rest)
        if num in dbg.stopped:
            dbg.resume(num)
        else:
            T = emu.task(num)
            if T is None or not T.paused:
                raise MonitorError(f"*Program not stopped* (task {num})")
            emu.proceed(num)
        return ""

    def cmd_SSTEP(self, rest: str) -> str:
        return self._step_cmd(rest, "over")

    def cmd_XSTEP(self, rest: str) -> str:
        return self._step_cmd(rest, "in")

    def _step_cmd(self, rest: str, kind: str) -> str:
        _, dbg = self._need()
        num = self._task_arg(rest)
        if num not in dbg.stopped:
            raise MonitorError(f"*Program not stopped* (task {num}): set a BPT first")
        dbg.step(num, kind)
        return ""

    def cmd_BPT(self, rest: str) -> str:
        """``BPT program step`` sets, ``BPT -program step`` clears, ``BPT`` lists (UNCONFIRMED syntax)."""
        self._need()
        if not rest:
            return "\n".join(f"{p} step {s}" for p, s in sorted(self.bpts)) or "no breakpoints"
        m = re.match(r"(-)?\s*([A-Za-z][\w.]*)\s*,?\s*(\d+)\s*\Z", rest)
        if m is None:
            raise MonitorError("*Invalid format* BPT [-]program step")
        prog, step = norm(m.group(2)), int(m.group(3))
        if m.group(1):
            self.bpts.pop((prog, step), None)
            self._apply(prog)
            return ""
        return self._set_bpt(prog, step)

    def _set_bpt(self, prog: str, step: int) -> str:
        p = self.emu.rt.module.programs.get(prog)
        if p is None:
            self.bpts.pop((prog, step), None)
            raise MonitorError(f"*Undefined program* {prog}")
        self.bpts[(prog, step)] = p.line + step - 1
        bps = self._apply(prog)
        line = p.line + step - 1
        if not any(b.verified and b.requested == line for b in bps):
            self.bpts.pop((prog, step), None)
            self._apply(prog)
            raise MonitorError(f"*Invalid step number* {prog} step {step}: no instruction there")
        return ""

    def _apply(self, prog: str) -> list:
        p = self.emu.rt.module.programs[prog]
        dbg = self.debugger
        path = dbg.path_of(p.file)
        lines = [ln for (q, _), ln in self.bpts.items()
                 if self.emu.rt.module.programs.get(q) is not None and self.emu.rt.module.programs[q].file == p.file]
        return dbg.set_breakpoints(path, [{"line": ln} for ln in lines])

    def _step(self, frame: Any) -> int:
        return frame.line - frame.prog.line + 1

    def cmd_STATUS(self, rest: str) -> str:
        emu, dbg = self._need()
        rows = ["Task  Status     Program          Step  Cycles"]
        for n, T in sorted(emu.rt.tasks.items()):
            status = T.state
            step = ""
            if n in dbg.stopped and T.frames:
                status = "stopped"
                step = str(self._step(T.frames[0]))
            elif T.state == "running":
                frames = dbg.frames(n)
                step = str(self._step(frames[0])) if frames else ""
            rows.append(f"{n:<5} {status:<10} {T.program:<16} {step:>4}  {T.cycles}")
        return "\n".join(rows)

    def cmd_LISTR(self, rest: str) -> str:
        _, dbg = self._need()
        return "\n".join(f"{e} = {render(dbg.evaluate(e, None))}" for e in _split_args(rest))

    cmd_LISTS = cmd_LISTR

    def cmd_LISTL(self, rest: str) -> str:
        _, dbg = self._need()
        out = ["              X         Y         Z         y         p         r"]
        for e in _split_args(rest):
            v = dbg.evaluate(e, None)
            if not hasattr(v, "decompose"):
                raise MonitorError(f"*Invalid argument* {e} is not a location")
            out.append(f"{e:<10}" + "".join(f"{x:10.3f}" for x in v.decompose()))
        return "\n".join(out)

    def cmd_LISTP(self, rest: str) -> str:
        emu, _ = self._need()
        p = emu.rt.module.programs.get(norm(rest))
        if p is None:
            raise MonitorError(f"*Undefined program* {rest}")
        return "\n".join(f"{ln - p.line + 1:5d} {text}" for ln, text in sorted(p.source.items()))

    def cmd_DIRECTORY(self, rest: str) -> str:
        emu, _ = self._need()
        return "\n".join(sorted(emu.rt.module.programs))

    def cmd_WHERE(self, rest: str) -> str:
        emu, _ = self._need()
        ctl = emu.controller
        pose = ctl.here_at(emu.time_s)
        joints = ctl.joints_at(emu.time_s)
        return ("     X         Y         Z         y         p         r\n"
                + "".join(f"{v:10.3f}" for v in (pose.x, pose.y, pose.z, pose.yaw, pose.pitch, pose.roll))
                + "\nJoints\n" + "".join(f"{v:10.3f}" for v in joints))

    def cmd_HERE(self, rest: str) -> str:
        emu, dbg = self._need()
        from aioadept.vplus.locations import Transform

        name = rest.strip()
        if not name:
            raise MonitorError("*Missing argument* HERE location")
        if name.startswith("#"):
            from aioadept.vplus.locations import ppoint

            emu.rt.globals[norm(name)] = ppoint(*emu.controller.joints_at(emu.time_s))
        else:
            emu.rt.globals[norm(name)] = Transform.from_pose(emu.controller.here_at(emu.time_s))
        return self.cmd_LISTL(name) if not name.startswith("#") else self.cmd_LISTR(name)

    def cmd_DO(self, rest: str) -> str:
        emu, _ = self._need()
        from aioadept.vplus.compiler import compile_program
        from aioadept.vplus.loader import Module, load_text

        module = load_text(f".PROGRAM monitor.do()\n{rest}\n.END\n", "<DO>", Module())
        prog = module.programs.get("monitor.do")
        problems = module.problems or (prog.problems if prog is not None else [])
        if prog is None or problems:
            raise MonitorError(str(problems[0].message) if problems else "*Invalid instruction*")
        src, consts, problems = compile_program(prog, emu.rt.doubles())
        if problems:
            raise MonitorError(problems[0].message)
        ns = emu.rt._namespace()
        ns["_K"] = consts
        exec(compile(src, "<V+ DO>", "exec"), ns)  # noqa: S102 - V+ code compiled by our own compiler
        emu.rt.programs["monitor.do"] = ns["_prog"]
        T = emu.task(0)
        if T is not None and T.state in ("running", "paused"):
            raise MonitorError("*Task already active* (DO runs in task 0)")
        emu.rt.start_task(0, "monitor.do")
        return ""

    def cmd_TYPE(self, rest: str) -> str:
        return self.cmd_DO("TYPE " + rest)

    def cmd_SPEED(self, rest: str) -> str:
        emu, _ = self._need()
        ctl = emu.controller
        if not rest:
            return f"monitor speed {ctl.monitor_speed_pct:g}"
        try:
            pct = float(rest)
        except ValueError:
            raise MonitorError(f"*Invalid argument* SPEED {rest}") from None
        if not 0 < pct <= 100:
            raise MonitorError(f"*Value out of range* SPEED {rest} (0 < speed <= 100)")
        ctl.monitor_speed_pct = pct
        return ""

    def cmd_PANIC(self, rest: str) -> str:
        emu, _ = self._need()
        if emu.rt.robot is not None:
            emu.rt.robot.brake(emu.time_s)
        return "*PANIC command*: the arm is braked"

    def end(self) -> None:
        """Leaving the monitor: the arm is braked; every task is aborted, or (attached to a sim) its breakpoints
        go and its stopped tasks go on (the server serves on)."""
        if self.debugger is None:
            return
        if self.remote:
            self.bpts.clear()
            self.debugger.detach()
        else:
            self.debugger.end()


def _base(path: str) -> str:
    import os

    return os.path.basename(path)


def _split_args(text: str | None) -> list[str]:
    """Comma-separated expressions, commas inside parentheses or strings kept."""
    out, depth, cur, quote = [], 0, "", False
    for ch in text or "":
        if ch == '"':
            quote = not quote
        elif not quote and ch == "(":
            depth += 1
        elif not quote and ch == ")":
            depth -= 1
        elif not quote and ch == "," and depth == 0:
            out.append(cur.strip())
            cur = ""
            continue
        cur += ch
    if cur.strip():
        out.append(cur.strip())
    return out


# -- serving ---------------------------------------------------------------------------------------------------

async def serve_lines(emu: Any, debugger: Debugger, first: bytes, reader: asyncio.StreamReader,
                      writer: asyncio.StreamWriter) -> None:
    """A monitor session on a connection to ``sim --debug-port``: each line a command, its reply and the prompt
    back; ``Break at`` lines whenever a task stops. ``EXIT`` or the end of the connection ends it."""
    def out(text: str) -> None:
        if text and not writer.is_closing():
            writer.write(text.replace("\n", "\r\n").encode() + b"\r\n")

    mon = Monitor(lambda files: None, out)
    mon.attach(emu, debugger)
    line = first
    try:
        while line:
            cmd = line.decode("latin-1").strip()
            if cmd.upper() in ("EXIT", "QUIT"):
                break
            out(mon.command(cmd))
            writer.write(PROMPT.encode())
            await writer.drain()
            line = await reader.readline()
    except ConnectionError:
        pass
    finally:
        mon.end()


async def connect(host: str, port: int) -> int:
    """``aioadept vplus monitor --connect 127.0.0.1:PORT``: this terminal's lines to a sim's monitor session."""
    import functools

    try:
        import readline  # noqa: F401 - line editing and history for input()
    except ImportError:  # pragma: no cover
        pass
    reader, writer = await asyncio.open_connection(host, port)
    writer.write(b"\n")                      # an empty command: the prompt comes back

    async def pump() -> None:
        while data := await reader.read(4096):
            sys.stdout.write(data.decode("latin-1").replace("\r\n", "\n"))
            sys.stdout.flush()

    shown = asyncio.ensure_future(pump())
    loop = asyncio.get_running_loop()
    while not shown.done():
        try:
            line = await loop.run_in_executor(None, functools.partial(input, ""))
        except EOFError:
            break
        writer.write(line.encode("latin-1", "replace") + b"\n")
    if not writer.is_closing():
        writer.write(b"EXIT\n")              # the replies still on their way are shown, then the sim closes
        try:
            await asyncio.wait_for(shown, 10)
        except asyncio.TimeoutError:
            shown.cancel()
        writer.close()
    return 0


async def serve(files: list[str], time_scale: float = 1.0) -> int:
    """The monitor on this terminal until end of input: the emulator runs meanwhile."""
    import functools

    try:
        import readline  # noqa: F401 - line editing and history for input()
    except ImportError:  # pragma: no cover - platforms without readline
        pass
    from aioadept.sim.server import SimOptions
    from aioadept.vplus import Emulator, RealClock
    from aioadept.vplus.iodev import Network
    from aioadept.vplus.loader import load_files
    from aioadept.vplus.robot import RobotDevice

    def out(text: str) -> None:
        if text:
            print(text, flush=True)

    ctl = SimOptions(time_scale=time_scale, state_endpoint=None).make_controller()

    def make(paths: list[str]) -> Any:
        emu = Emulator(load_files(paths), robot=RobotDevice(ctl), clock=RealClock(),
                       console=lambda task, text: out(text))
        emu.rt.devices = Network("127.0.0.1", {}, lambda vport, host, port: out(f"({vport} on {host}:{port})"))
        return emu

    mon = Monitor(make, out)
    loop = asyncio.get_running_loop()
    serving: list[tuple[asyncio.Event, asyncio.Future]] = []

    def new_emulator(emu: Any) -> None:
        for stop, _ in serving:
            stop.set()
        stop = asyncio.Event()
        serving.append((stop, asyncio.ensure_future(emu.serve(stop))))

    mon.on_new_emulator = new_emulator
    for f in files:
        out(mon.command(f"LOAD {f}"))
    while True:
        try:
            line = await loop.run_in_executor(None, functools.partial(input, PROMPT))
        except EOFError:
            break
        if line.strip().upper() in ("EXIT", "QUIT"):
            break
        out(mon.command(line))
    mon.end()
    for stop, _ in serving:
        stop.set()
    await asyncio.gather(*(f for _, f in serving), return_exceptions=True)
    print(file=sys.stdout, flush=True)
    return 0
