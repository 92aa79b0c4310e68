"""``aioadept vplus dap``: a Debug Adapter Protocol server for V+ code on the emulator, with the simulated arm.

A thin I/O layer over :mod:`aioadept.vplus.debugger`: it frames messages (``Content-Length`` headers and JSON, on
stdin/stdout or one TCP connection on 127.0.0.1 with ``--listen``), keeps the handles the protocol hands out
(frames, variable containers) and runs the emulator in real time on the same asyncio loop. V+ tasks are the
threads; sources are the ``.V2`` files with their real line numbers.

The framing is ours (about 40 lines): the maintained Python packages for the protocol either bring types only
(``dap-types``, pydantic models, no framing or dispatch) or are a debugger for Python programs whose framing is
not a public API (``debugpy``); plain dicts keep the adapter as small as the protocol's JSON.

``launch`` arguments (:mod:`aioadept.vplus.daplaunch`): ``modules`` (list of .V2 paths), ``program`` (the program the task runs, e.g. ``rs.main``),
``task`` (default 0), ``portMap`` (V+ port -> host port, as ``sim --map-port``), ``timeScale``, ``disk`` (the
folder of disk files), ``cell`` (a cell file with a ``[world]`` table, or a world .json), ``stopOnEntry``.
``disconnect`` and ``terminate`` brake the arm and end the emulator.
"""

from __future__ import annotations

import asyncio
import json
import sys
from collections.abc import Callable
from typing import Any

from aioadept.vplus.daplaunch import LaunchError, launch_args, make_emulator
from aioadept.vplus.debugger import EXCEPTION_MODES, DebugError, Debugger, children, render
from aioadept.vplus.trace import Frame

CAPABILITIES = {
    "supportsConfigurationDoneRequest": True,
    "supportsConditionalBreakpoints": True,
    "supportsHitConditionalBreakpoints": True,
    "supportsLogPoints": True,
    "supportsEvaluateForHovers": True,
    "supportsSetVariable": True,
    "supportsTerminateRequest": True,
    "exceptionBreakpointFilters": [
        {"filter": "all", "label": "All V+ errors", "default": False},
        {"filter": "untrapped", "label": "Untrapped V+ errors (no REACTE)", "default": True},
    ],
}
# -- framing ---------------------------------------------------------------------------------------------------

async def read_message(reader: asyncio.StreamReader, first: bytes | None = None) -> dict | None:
    """One message, or None at the end of the stream (``first``: its first header line, already read)."""
    length = None
    while True:
        line, first = (first, None) if first is not None else (await reader.readline(), None)
        if not line:
            return None
        line = line.strip()
        if not line:
            break
        name, _, value = line.decode("ascii", "replace").partition(":")
        if name.strip().lower() == "content-length":
            length = int(value)
    if length is None:
        raise ValueError("a message without Content-Length")
    return json.loads(await reader.readexactly(length))


def frame_message(msg: dict) -> bytes:
    body = json.dumps(msg, separators=(",", ":")).encode()
    return b"Content-Length: %d\r\n\r\n" % len(body) + body


# -- the adapter -----------------------------------------------------------------------------------------------

class Adapter:
    """One debug session: requests in (:meth:`handle`), responses and events out through ``send``."""

    def __init__(self, send: Callable[[bytes], None], attached: tuple[Any, Debugger] | None = None) -> None:
        """``attached``: (emulator, its debugger) of a running ``aioadept sim --vplus --debug-port``: the session
        attaches to it instead of launching."""
        self._send = send
        self.seq = 0
        self.emu: Any = None
        self.debugger: Debugger | None = None
        self.attached = attached is not None
        if attached is not None:
            self.emu, self.debugger = attached
        self.stop = asyncio.Event()          # set: the emulator stops serving
        self.done = asyncio.Event()          # set: the session is over
        self._serving: asyncio.Future | None = None
        self._launch: dict | None = None     # the launch request, answered at configurationDone
        self._args: dict = {}
        self._refs: dict[int, tuple] = {}
        self._frames: dict[int, Frame] = {}
        self._ended = False

    # -- output ---------------------------------------------------------------------------------------------
    def send(self, msg: dict) -> None:
        self.seq += 1
        msg["seq"] = self.seq
        self._send(frame_message(msg))

    def event(self, name: str, body: dict | None = None) -> None:
        self.send({"type": "event", "event": name, "body": body or {}})

    def respond(self, req: dict, body: dict | None = None, error: str | None = None) -> None:
        msg = {"type": "response", "request_seq": req["seq"], "command": req["command"], "success": error is None}
        if error is not None:
            msg["message"] = error
            msg["body"] = {"error": {"id": 1, "format": error, "showUser": True}}
        else:
            msg["body"] = body or {}
        self.send(msg)

    # -- dispatch ---------------------------------------------------------------------------------------------
    async def handle(self, req: dict) -> None:
        command = str(req.get("command", ""))
        req.setdefault("seq", 0)
        method = getattr(self, "req_" + command, None)
        if method is None:
            self.respond(req, error=f"{command}: not supported by the V+ debugger")
            return
        try:
            body = method(req.get("arguments") or {}, req)
        except (DebugError, LaunchError) as exc:
            self.respond(req, error=str(exc))
            return
        except (KeyError, TypeError, ValueError) as exc:
            # a request without an argument it needs, or of the wrong type: an error response, the session goes on
            self.respond(req, error=f"{command}: bad arguments ({type(exc).__name__}: {exc})")
            return
        if body is not _LATER:
            self.respond(req, body)

    def req_initialize(self, args: dict, req: dict) -> dict:
        return CAPABILITIES

    def req_attach(self, args: dict, req: dict) -> dict:
        if not self.attached or self.debugger is None:
            raise DebugError("attach: nothing to attach to here (connect to a running aioadept sim --vplus with "
                             "a debug port, or launch)")
        self.debugger.on_event = self.event
        self.event("initialized")
        return {}

    def req_launch(self, args: dict, req: dict) -> object:
        if self.attached:
            raise LaunchError("launch: this session is attached to a running emulator (use attach)")
        self._args = launch_args(args)
        self.emu = make_emulator(self._args, self._console, self._listening)
        for p in self.emu.problems:
            self._output(f"{p}\n", "stderr")
        self.debugger = Debugger(self.emu.rt, self.event)
        self.emu.rt.on_task_end = self._task_ended
        self._launch = req
        self.event("initialized")
        return _LATER

    def req_configurationDone(self, args: dict, req: dict) -> dict:
        self.respond(req)
        launch, self._launch = self._launch, None
        if launch is None:
            return _LATER
        a = self._args
        try:
            self.emu.execute(a["task"], a["program"])
        except Exception as exc:  # noqa: BLE001 - a V+ error starting the task: the launch fails with its text
            self.respond(launch, error=str(exc))
            return _LATER
        if a["stopOnEntry"]:
            self.debugger.stop_on_entry(a["task"])
        self._serving = asyncio.ensure_future(self.emu.serve(self.stop))
        self._serving.add_done_callback(self._served)
        self.respond(launch)
        return _LATER

    def req_setBreakpoints(self, args: dict, req: dict) -> dict:
        source = args.get("source") or {}
        path = source.get("path")
        if not path:
            raise DebugError("setBreakpoints: the source has no path")
        bps = self._dbg().set_breakpoints(path, args.get("breakpoints") or [])
        return {"breakpoints": [{"id": b.id, "verified": b.verified, "line": b.line, "source": {"path": path},
                                 **({} if b.verified else {"message": "no V+ statement at or after this line"})}
                                for b in bps]}

    def req_setExceptionBreakpoints(self, args: dict, req: dict) -> dict:
        filters = set(args.get("filters") or [])
        self._dbg().exceptions = next((m for m in EXCEPTION_MODES if m in filters), "none")
        return {}

    def req_threads(self, args: dict, req: dict) -> dict:
        if self.debugger is None:
            return {"threads": []}
        return {"threads": [{"id": n, "name": name} for n, name in self.debugger.threads()]}

    def req_stackTrace(self, args: dict, req: dict) -> dict:
        dbg = self._dbg()
        frames = dbg.frames(int(args["threadId"]))
        out = []
        for f in frames:
            fid = self._ref(("frame", f))
            self._frames[fid] = f
            path = dbg.path_of(f.file)
            argtext = ", ".join(render(v) for _, v, _ in f.args())
            out.append({"id": fid, "name": f"{f.program}({argtext})", "line": f.line, "column": 1,
                        "source": {"name": f.file, "path": path}})
        return {"stackFrames": out, "totalFrames": len(out)}

    def req_scopes(self, args: dict, req: dict) -> dict:
        f = self._frame(args.get("frameId"))
        assert f is not None
        return {"scopes": [{"name": name, "variablesReference": self._ref(("scope", f, name)),
                            "expensive": name == "Globals"} for name in ("AUTO", "LOCAL", "Globals")]}

    def req_variables(self, args: dict, req: dict) -> dict:
        ref = self._refs.get(int(args["variablesReference"]))
        if ref is None:
            raise DebugError("variables: no such reference (the task has gone on)")
        if ref[0] == "scope":
            _, f, scope = ref
            items = [(n, v, f, n.removesuffix("[]")) for n, v in self._dbg().scopes(f)[scope]]
        else:
            _, f, base, value = ref
            items = [(n, v, f, f"{base}{n}" if n.startswith("[") else None) for n, v in children(value)]
        return {"variables": [self._variable(n, v, f, expr) for n, v, f, expr in items]}

    def _variable(self, name: str, value: Any, frame: Frame, expr: str | None) -> dict:
        kids = children(value)
        ref = self._ref(("value", frame, expr or name, value)) if kids else 0
        out = {"name": name, "value": render(value), "variablesReference": ref}
        if expr is not None:
            out["evaluateName"] = expr
        return out

    def req_setVariable(self, args: dict, req: dict) -> dict:
        ref = self._refs.get(int(args["variablesReference"]))
        if ref is None:
            raise DebugError("setVariable: no such reference")
        name = args["name"]
        if ref[0] == "scope":
            frame, target = ref[1], name.removesuffix("[]")
        elif name.startswith("["):
            frame, target = ref[1], f"{ref[2]}{name}"
        else:
            raise DebugError(f"{name}: set the whole value (SET {ref[2]} = TRANS(...))")
        value = self._dbg().set_variable(frame, target, str(args["value"]))
        return {"value": render(value), "variablesReference": 0}

    def req_evaluate(self, args: dict, req: dict) -> dict:
        f = self._frame(args.get("frameId"))
        value = self._dbg().evaluate(str(args["expression"]), f)
        kids = children(value)
        return {"result": render(value),
                "variablesReference": self._ref(("value", f, args["expression"], value)) if kids else 0}

    def req_continue(self, args: dict, req: dict) -> dict:
        single = bool(args.get("singleThread"))
        self._dbg().resume(int(args["threadId"]) if single else None)
        return {"allThreadsContinued": not single}

    def req_next(self, args: dict, req: dict) -> dict:
        self._dbg().step(int(args["threadId"]), "over")
        return {}

    def req_stepIn(self, args: dict, req: dict) -> dict:
        self._dbg().step(int(args["threadId"]), "in")
        return {}

    def req_stepOut(self, args: dict, req: dict) -> dict:
        self._dbg().step(int(args["threadId"]), "out")
        return {}

    def req_pause(self, args: dict, req: dict) -> dict:
        self._dbg().pause(int(args["threadId"]) if "threadId" in args else None)
        return {}

    def req_terminate(self, args: dict, req: dict) -> dict:
        if self.attached and self.debugger is not None:
            self.debugger.end()           # brake, abort every task: the sim's supervisor ends the server
        self.end()
        return {}

    def req_disconnect(self, args: dict, req: dict) -> object:
        self.end()
        self.respond(req)
        self.done.set()
        return _LATER

    # -- the session --------------------------------------------------------------------------------------------
    def end(self) -> None:
        """Brake the arm, abort every task, stop the emulator; ``terminated`` once."""
        if self._ended:
            return
        self._ended = True
        if self.attached:
            if self.debugger is not None:
                self.debugger.detach()
            self.event("terminated")
            return
        if self.debugger is not None:
            self.emu.rt.on_task_end = None
            self.debugger.end()
            if self.emu.rt.devices is not None:
                from aioadept.vplus import iodev

                iodev.close_all(self.emu.rt)
        self.stop.set()
        self.event("terminated")

    def _served(self, fut: asyncio.Future) -> None:
        if not fut.cancelled() and fut.exception() is not None:
            self._output(f"emulator internal error: {fut.exception()}\n", "stderr")
            self.end()

    def _task_ended(self, T: Any) -> None:
        self.debugger.stopped.pop(T.num, None)
        self.event("thread", {"reason": "exited", "threadId": T.num})
        if T.error is not None:
            self._output(f"task {T.num} ({T.program}) stopped: {T.error}\n", "stderr")
        if not any(t.state in ("running", "paused") and t is not T for t in self.emu.rt.tasks.values()):
            asyncio.get_running_loop().call_soon(self.end)

    def _console(self, task: int, text: str) -> None:
        self._output(f"[{task}] {text}\n", "stdout")

    def _listening(self, vport: int, host: str, port: int) -> None:
        self._output(f"READY host={host} port={port} vport={vport}\n", "console")

    def _output(self, text: str, category: str = "console") -> None:
        self.event("output", {"category": category, "output": text})

    def _dbg(self) -> Debugger:
        if self.debugger is None:
            raise DebugError("no program is launched")
        return self.debugger

    def _ref(self, what: tuple) -> int:
        n = len(self._refs) + 1
        self._refs[n] = what
        return n

    def _frame(self, fid: Any) -> Frame | None:
        if fid is None:
            return None
        f = self._frames.get(int(fid))
        if f is None:
            raise DebugError(f"frame {fid}: no such frame (the task has gone on)")
        return f


_LATER = object()
"""A request method's result when it responds itself (or later)."""


# -- serving ---------------------------------------------------------------------------------------------------

async def session(reader: asyncio.StreamReader, send: Callable[[bytes], None]) -> None:
    """Serve one debug session until ``disconnect`` or the end of the input (which also ends the emulator)."""
    await run(Adapter(send), reader)


async def run(adapter: Adapter, reader: asyncio.StreamReader, first: bytes | None = None) -> None:
    """Serve requests until ``disconnect``, the end of the input or a message that is not DAP (which ends the
    session as the end of the input does, after an output event saying why)."""
    try:
        while not adapter.done.is_set():
            try:
                msg = await read_message(reader, first)
                first = None
            except (ValueError, asyncio.IncompleteReadError) as exc:
                adapter._output(f"not a Debug Adapter Protocol message ({exc}): the session ends\n", "stderr")
                break
            if msg is None:
                break
            if isinstance(msg, dict) and msg.get("type") == "request":
                await adapter.handle(msg)
    finally:
        adapter.end()
        if adapter._serving is not None:
            await asyncio.gather(adapter._serving, return_exceptions=True)


async def serve_attach(emu: Any, debugger: Debugger, host: str, port: int) -> asyncio.Server:
    """Serve ``attach`` sessions to a running emulator on ``host:port`` (loopback), one at a time (a second
    connection is closed at once). A connection whose first line is no DAP header is a V+ monitor session
    (``aioadept vplus monitor --connect``: lines in, replies out, :func:`aioadept.vplus.monitor.serve_lines`)."""
    busy = [False]

    async def one(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if busy[0]:
            writer.close()
            return
        busy[0] = True
        try:
            first = await reader.readline()
            if not first.lower().startswith(b"content-length"):
                from aioadept.vplus.monitor import serve_lines

                await serve_lines(emu, debugger, first, reader, writer)
                return
            adapter = Adapter(writer.write, attached=(emu, debugger))
            await run(adapter, reader, first)     # its end (even a client gone) detaches
            await writer.drain()
        except ConnectionError:
            pass
        finally:
            busy[0] = False
            writer.close()

    return await asyncio.start_server(one, host, port)


async def serve_stdio() -> None:
    loop = asyncio.get_running_loop()
    reader = asyncio.StreamReader()
    await loop.connect_read_pipe(lambda: asyncio.StreamReaderProtocol(reader), sys.stdin)
    out = sys.stdout.buffer

    def send(data: bytes) -> None:
        out.write(data)
        out.flush()

    await session(reader, send)


async def serve_tcp(host: str, port: int, ready: Callable[[int], None] | None = None) -> None:
    """Serve one session on the first connection to ``host:port`` (loopback only)."""
    over = asyncio.Event()

    async def one(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if over.is_set():
            writer.close()
            return
        try:
            await session(reader, writer.write)
            await writer.drain()
        finally:
            writer.close()
            over.set()

    server = await asyncio.start_server(one, host, port)
    if ready is not None:
        ready(server.sockets[0].getsockname()[1])
    async with server:
        await over.wait()


def parse_listen(text: str, option: str = "--listen") -> tuple[str, int]:
    """``127.0.0.1:PORT`` -> (host, port); ``ValueError`` naming ``option`` for anything but a loopback address
    and a port."""
    host, sep, port = text.rpartition(":")
    if not sep or host not in ("127.0.0.1", "localhost", "::1", "[::1]"):
        raise ValueError(f"{option} {text}: expected 127.0.0.1:PORT (the debugger is on loopback only)")
    try:
        n = int(port)
    except ValueError:
        raise ValueError(f"{option} {text}: {port!r} is not a port number") from None
    if not 0 < n < 65536:
        raise ValueError(f"{option} {text}: port out of range")
    return host.strip("[]"), n
