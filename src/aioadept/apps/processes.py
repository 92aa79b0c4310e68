"""Starting and supervising the cell's nodes as child processes.

Each node (``aioadept sim``, ``aioadept vision``) is a separate process, as on a real cell. A :class:`NodeProcess`
starts one with the same Python, waits for its ``READY key=value ...`` line (never a sleep), keeps its output in a
log file, notices when it dies, and on exit stops it with SIGINT, then SIGTERM, then SIGKILL. Each node runs in
its own session (a terminal's Ctrl-C reaches only the app, which stops the robot first); :func:`kill_all_now` is the
app's way out on a second Ctrl-C.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import shlex
import signal
import logging
import sys
from pathlib import Path
from typing import IO, Any

from aioadept.errors import NodeError

log = logging.getLogger(__name__)

# Process groups of the nodes started and not yet reaped, for kill_all_now() (a signal handler's exit path).
_LIVE_GROUPS: set[int] = set()


def _die_with_parent(parent_pid: int):
    """For the child, between fork and exec: on Linux, have the kernel send it SIGTERM when the process that started
    it dies, even by SIGKILL, so a killed demo or experiment never leaves a robot sim or a camera node running
    (prctl PR_SET_PDEATHSIG). Elsewhere a no-op."""

    def apply() -> None:
        if not sys.platform.startswith("linux"):
            return
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # 1 = PR_SET_PDEATHSIG
        if os.getppid() != parent_pid:  # the parent died before the call: nobody would send the signal
            os._exit(1)

    return apply


def kill_all_now() -> int:
    """SIGKILL the process group of every node still running; returns how many. Does not wait (exiting now)."""
    n = 0
    for pgid in list(_LIVE_GROUPS):
        try:
            os.killpg(pgid, signal.SIGKILL)
            n += 1
        except (ProcessLookupError, PermissionError):
            pass
        _LIVE_GROUPS.discard(pgid)
    return n


def parse_ready(line: str) -> dict[str, str]:
    """``READY host=127.0.0.1 port=1234`` -> ``{"host": "127.0.0.1", "port": "1234"}``."""
    fields = line.split()
    if not fields or fields[0] != "READY":
        raise ValueError(f"not a READY line: {line!r}")
    out: dict[str, str] = {}
    for f in fields[1:]:
        key, sep, value = f.partition("=")
        if sep:
            out[key] = value
    return out


class NodeProcess:
    """One node as a child process: ``async with NodeProcess("sim", ["sim", "--port", "0"]) as node: node.ready``."""

    def __init__(self, name: str, argv: list[str], *, log_path: Path | None = None, ready_timeout_s: float = 30.0,
                 env: dict[str, str] | None = None) -> None:
        self.name = name
        self.argv = [sys.executable, "-m", "aioadept", *argv]
        self.log_path = log_path
        self.ready_timeout_s = ready_timeout_s
        self.env = env
        self.ready: dict[str, str] = {}
        self.proc: asyncio.subprocess.Process | None = None
        self._log: IO[str] | None = None
        self._pumps: list[asyncio.Task[None]] = []
        self._tail: list[str] = []
        self._stopping = False

    @property
    def command_line(self) -> str:
        return shlex.join(self.argv)

    async def __aenter__(self) -> NodeProcess:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    async def start(self) -> dict[str, str]:
        env = dict(os.environ if self.env is None else self.env)
        env.setdefault("PYTHONUNBUFFERED", "1")
        if self.log_path is not None:
            try:
                self.log_path.parent.mkdir(parents=True, exist_ok=True)
                self._log = open(self.log_path, "w", encoding="utf-8")  # noqa: SIM115 - closed in stop()
            except OSError as exc:
                log.warning("%s runs without its log %s: %s", self.name, self.log_path, exc.strerror or exc)
            self._write_log(f"$ {self.command_line}")
        self.proc = await asyncio.create_subprocess_exec(
            *self.argv, stdin=asyncio.subprocess.DEVNULL, stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE, env=env, start_new_session=True, preexec_fn=_die_with_parent(os.getpid()))
        _LIVE_GROUPS.add(self.proc.pid)  # its own session: the pid is the group id
        assert self.proc.stdout is not None and self.proc.stderr is not None
        self._pumps.append(asyncio.create_task(self._pump(self.proc.stderr, "err")))
        try:
            async with asyncio.timeout(self.ready_timeout_s):
                while True:
                    raw = await self.proc.stdout.readline()
                    if not raw:
                        await self.proc.wait()
                        raise NodeError(f"{self.name} exited with code {self.proc.returncode} before it was ready:"
                                        f"\n{self.tail()}")
                    line = raw.decode(errors="replace").rstrip()
                    self._keep(line)
                    if line.startswith("READY"):
                        self.ready = parse_ready(line)
                        break
        except TimeoutError:
            await self.stop()
            raise NodeError(f"{self.name} did not report READY within {self.ready_timeout_s} s:\n{self.tail()}") from None
        except BaseException:
            await self.stop()
            raise
        self._pumps.append(asyncio.create_task(self._pump(self.proc.stdout, "out")))
        return self.ready

    async def _pump(self, stream: asyncio.StreamReader, _tag: str) -> None:
        while raw := await stream.readline():
            self._keep(raw.decode(errors="replace").rstrip())

    def _keep(self, line: str) -> None:
        self._write_log(line)
        self._tail.append(line)
        del self._tail[:-20]

    def _write_log(self, line: str) -> None:
        """The node's log is a by-product: a write the disk refuses (full, a file-size limit) ends the log with a
        warning, never the run, and the pump goes on draining the pipe so the node never blocks on it."""
        if self._log is None:
            return
        try:
            self._log.write(line + "\n")
            self._log.flush()
        except OSError as exc:
            log.warning("%s's log %s is cut short here: %s", self.name, self.log_path, exc.strerror or exc)
            self._close_log()

    def _close_log(self) -> None:
        log_file, self._log = self._log, None
        if log_file is not None:
            with contextlib.suppress(OSError):  # what is still buffered meets the same full disk
                log_file.close()

    def tail(self) -> str:
        """The last lines the node printed (for error messages)."""
        return "\n".join(f"  [{self.name}] {line}" for line in self._tail)

    @property
    def returncode(self) -> int | None:
        return None if self.proc is None else self.proc.returncode

    async def wait_exit(self) -> int:
        """Wait until the process exits on its own; returns its exit code."""
        assert self.proc is not None
        return await self.proc.wait()

    async def stop(self, *, grace_s: float = 5.0) -> int | None:
        """Stop the node: SIGINT, then SIGTERM, then SIGKILL, each after ``grace_s``. Idempotent."""
        proc = self.proc
        if proc is not None and proc.returncode is None:
            self._stopping = True
            for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, sig)
                try:
                    async with asyncio.timeout(grace_s):
                        await proc.wait()
                    break
                except TimeoutError:
                    continue
        if proc is not None:
            _LIVE_GROUPS.discard(proc.pid)
        for task in self._pumps:
            task.cancel()
        for task in self._pumps:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._pumps.clear()
        self._close_log()
        return None if proc is None else proc.returncode


async def watch(*nodes: NodeProcess) -> None:
    """Return never while all nodes run; raise :class:`NodeError` as soon as one exits on its own."""
    waits = {asyncio.create_task(n.wait_exit()): n for n in nodes}
    try:
        done, _ = await asyncio.wait(waits, return_when=asyncio.FIRST_COMPLETED)
        node = waits[next(iter(done))]
        what = f"{node.name} exited unexpectedly with code {node.returncode}"
        raise NodeError(f"{what}:\n{node.tail()}", headline=what)
    finally:
        for t in waits:
            t.cancel()
        await asyncio.gather(*waits, return_exceptions=True)


async def run_watched(coro: Any, *nodes: NodeProcess) -> Any:
    """Await ``coro``; if one of ``nodes`` exits first, cancel it and raise that node's :class:`NodeError`.

    The cancellation carries the cause (``NodeError: <node> exited unexpectedly with code N``, the words the
    app's failure line starts with), so a run that saves its folder while it is cancelled names the dead node
    as its error (:func:`aioadept.runs.folder.run_error`), not an interrupt."""
    main = asyncio.ensure_future(coro)
    if not nodes:
        return await main
    watcher = asyncio.create_task(watch(*nodes))
    try:
        await asyncio.wait({main, watcher}, return_when=asyncio.FIRST_COMPLETED)
    finally:
        died = watcher.done() and not watcher.cancelled() and watcher.exception() is not None
        if not main.done():
            cause = watcher.exception() if died else None
            main.cancel(None if cause is None else f"{type(cause).__name__}: {cause.headline}")
        if not watcher.done():
            watcher.cancel()
        await asyncio.gather(main, watcher, return_exceptions=True)
    if not main.cancelled() and main.exception() is None:
        return main.result()
    if died:
        raise watcher.exception()  # type: ignore[misc]
    return main.result()
