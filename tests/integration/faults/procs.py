"""Real subprocesses for the fault matrix: nodes that print ``READY k=v ...``, and a RobotClient in a process of
its own (``client_proc.py``) that can be killed, paused or cut off while it has commands in flight.

Starters read the READY line (never sleep); every process is ended on exit: SIGTERM, then SIGKILL after 5 s.
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sys
from collections.abc import AsyncIterator, Sequence
from dataclasses import dataclass
from pathlib import Path

AIOADEPT = str(Path(sys.executable).parent / "aioadept")
CLIENT_PROC = str(Path(__file__).with_name("client_proc.py"))


@dataclass
class Node:
    proc: asyncio.subprocess.Process
    ready: dict[str, str]
    log_path: Path | None = None

    @property
    def pid(self) -> int:
        return self.proc.pid

    def log(self) -> str:
        return self.log_path.read_text(errors="replace") if self.log_path and self.log_path.exists() else ""


async def _end(proc: asyncio.subprocess.Process) -> None:
    if proc.returncode is None:
        with contextlib.suppress(ProcessLookupError):
            proc.send_signal(signal.SIGCONT)  # a paused process cannot act on SIGTERM
            proc.send_signal(signal.SIGTERM)
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(5):
                await proc.wait()
    if proc.returncode is None:
        with contextlib.suppress(ProcessLookupError):
            proc.kill()
        await proc.wait()


@contextlib.asynccontextmanager
async def node(argv: Sequence[str], *, log_path: Path | None = None,
               ready_timeout_s: float = 20.0) -> AsyncIterator[Node]:
    """Start ``argv``; wait for its ``READY`` line on stdout; yield a :class:`Node` with the READY fields.

    stderr goes to ``log_path`` (a file, not a pipe: a chatty node must never block on a full pipe).
    """
    log = open(log_path, "wb") if log_path else None
    proc = await asyncio.create_subprocess_exec(*argv, stdout=asyncio.subprocess.PIPE,
                                                stderr=log if log else asyncio.subprocess.DEVNULL)
    try:
        assert proc.stdout is not None
        async with asyncio.timeout(ready_timeout_s):
            line = (await proc.stdout.readline()).decode()
        if not line.startswith("READY"):
            await _end(proc)
            text = log_path.read_text(errors="replace") if log_path else ""
            raise AssertionError(f"{argv[0]}: no READY line, got {line!r}\n{text}")
        yield Node(proc, dict(f.split("=", 1) for f in line.split()[1:]), log_path)
    finally:
        await _end(proc)
        if log:
            log.close()


def sim_node(*args: str, log_path: Path | None = None):
    """``aioadept sim --port 0 ARGS`` as a subprocess (see :func:`node`)."""
    return node([AIOADEPT, "sim", "--port", "0", *args], log_path=log_path)


def vision_node(request_ep: str, response_ep: str, *args: str, log_path: Path | None = None):
    """``aioadept vision`` bound on the given endpoints (port 0 allowed) as a subprocess (see :func:`node`)."""
    return node([AIOADEPT, "vision", "--request-endpoint", request_ep, "--response-endpoint", response_ep, *args],
                log_path=log_path)


@dataclass
class ClientProc:
    """A RobotClient in its own process (``client_proc.py``): ``sent`` are the IDs it wrote in one write,
    ``acked`` the ``(id, status)`` of the first acks it was told to wait for."""

    proc: asyncio.subprocess.Process
    sent: list[str]
    acked: list[tuple[str, str]]

    @property
    def pid(self) -> int:
        return self.proc.pid


@contextlib.asynccontextmanager
async def client_proc(host: str, port: int, wait_acks: int, *calls: str,
                      prefix: Sequence[str] = ()) -> AsyncIterator[ClientProc]:
    """Run ``client_proc.py``: it connects, writes ``calls`` (``skill[:a,b,...]``) in ONE write, waits for the
    first ``wait_acks`` acks, reports them, and then blocks forever (until killed). ``prefix`` runs it under
    another command (``ip netns exec NS``)."""
    proc = await asyncio.create_subprocess_exec(
        *prefix, sys.executable, CLIENT_PROC, host, str(port), str(wait_acks), *calls,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    try:
        assert proc.stdout is not None and proc.stderr is not None
        async with asyncio.timeout(20):
            sent_line = (await proc.stdout.readline()).decode()
            acked_line = (await proc.stdout.readline()).decode() if sent_line.startswith("SENT") else ""
        if not acked_line.startswith("ACKED"):
            await _end(proc)
            raise AssertionError(f"client process: {sent_line!r} {acked_line!r}\n"
                                 f"{(await proc.stderr.read()).decode(errors='replace')}")
        sent = sent_line.split()[1].split(",")
        acked = [tuple(a.split("=", 1)) for a in acked_line.split()[1:]]
        yield ClientProc(proc, sent, acked)  # type: ignore[arg-type]
    finally:
        await _end(proc)


def rss_kib(pid: int) -> int:
    """Resident set size of a process (Linux ``/proc``), KiB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise RuntimeError(f"no VmRSS for pid {pid}")
