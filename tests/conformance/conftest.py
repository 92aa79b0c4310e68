"""One RobotServer conformance suite, run against every backend as a real ``aioadept sim`` subprocess.

Backends (the ``server`` fixture's params):

- ``python``: ``aioadept sim`` with its Python skill table (the default backend);
- ``vplus``: ``aioadept sim --vplus vplus/rserver.V2 vplus/rsskills.V2 vplus/rsconfig.V2 --run rs.main``, the
  shipped V+ server running on the V+ emulator;
- ``adeptserver``: ``examples/vplus/adeptserver_style.V2`` on the emulator, a server in the style of the paper's
  original AdeptServer. It speaks only the original protocol (plain ``done`` acks, no error acks, no stop), so
  only tests marked ``@pytest.mark.adeptserver`` run against it (the ``any_server`` fixture).

The V+ backends need the emulator's ``--vplus`` option; should it ever be missing they are skipped with a loud
reason, never silently. ``--map-port 1234=P`` maps the program's ``FOPEN /LOCAL_PORT 1234`` to a free port P
on 127.0.0.1, and the process prints ``READY ... port=P`` once the program listens; the test connects there.
The stop port (docs/protocol.md 4.2.1) is mapped the same way (``--map-port 1235=Q``; the Python sim:
``--stop-port Q``), so ``Server.stop_port`` is known before the server starts.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from aioadept.protocol import Ack, parse_ack
from aioadept.testing.nodes import running_node
from aioadept.ports import free_port as _free_port

ROOT = Path(__file__).resolve().parents[2]
VPLUS_FILES = [str(ROOT / "vplus" / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]
ADEPTSERVER_FILES = [str(ROOT / "examples" / "vplus" / f) for f in ("adeptserver_style.V2",)]
VPLUS_PORT = 1234  # the port both V+ servers FOPEN (rs.config, adeptserver_style)
VPLUS_STOP_PORT = 1235  # the shipped server's stop port (rs.sport)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "adeptserver: also runs against the AdeptServer-style V+ example")


def vplus_cli_available() -> bool:
    from aioadept.cli.sim import build_parser

    return any("--vplus" in a.option_strings for a in build_parser()._actions)


NO_VPLUS = ("LOUD SKIP: `aioadept sim --vplus` does not exist yet, so the V+ backend of the conformance suite "
            "cannot run. It runs for real as soon as the emulator's CLI lands.")


@dataclass
class Server:
    """A running backend: where to connect and what it is."""

    backend: str
    host: str
    port: int
    log: Path
    stop_port: int | None = None

    async def connect_stop_port(self) -> Line:
        assert self.stop_port is not None, f"{self.backend} has no stop port"
        reader, writer = await asyncio.open_connection(self.host, self.stop_port)
        return Line(reader, writer)

    async def connect(self) -> Line:
        reader, writer = await asyncio.open_connection(self.host, self.port)
        return Line(reader, writer)


class Line:
    """A raw protocol connection: write bytes, read acks one line at a time (parsed with aioadept.protocol)."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader = reader
        self.writer = writer

    async def send(self, *lines: str | bytes) -> None:
        data = b"".join((ln.encode() if isinstance(ln, str) else ln) + b"\r\n" for ln in lines)
        self.writer.write(data)
        await self.writer.drain()

    async def raw(self, timeout: float = 15.0) -> bytes:
        async with asyncio.timeout(timeout):
            line = await self.reader.readuntil(b"\r\n")
        return line

    async def ack(self, timeout: float = 15.0) -> Ack:
        return parse_ack((await self.raw(timeout))[:-2])

    async def acks(self, n: int, timeout: float = 15.0) -> list[Ack]:
        return [await self.ack(timeout) for _ in range(n)]

    async def close(self) -> None:
        self.writer.close()
        with contextlib.suppress(OSError):
            await self.writer.wait_closed()


def _argv(backend: str, port: int, stop_port: int, extra: tuple[str, ...]) -> list[str]:
    common = ["--state-endpoint", "none", *extra]
    if backend == "python":
        return ["--port", "0", "--stop-port", str(stop_port), *common]
    files = VPLUS_FILES if backend == "vplus" else ADEPTSERVER_FILES
    prog = "rs.main" if backend == "vplus" else "adept.main"
    return ["--vplus", *files, "--run", prog, "--map-port", f"{VPLUS_PORT}={port}",
            "--map-port", f"{VPLUS_STOP_PORT}={stop_port}", *common]


async def _wait_listening(host: str, port: int, timeout_s: float = 20.0) -> None:
    """The V+ server prints READY when its first port listens; its stop port opens a moment later."""
    async with asyncio.timeout(timeout_s):
        while True:
            try:
                _, writer = await asyncio.open_connection(host, port)
            except OSError:
                await asyncio.sleep(0.02)
                continue
            writer.close()
            with contextlib.suppress(OSError):
                await writer.wait_closed()
            return


@contextlib.asynccontextmanager
async def start(backend: str, tmp_path: Path, *extra: str) -> AsyncIterator[Server]:
    if backend != "python" and not vplus_cli_available():
        pytest.skip(NO_VPLUS)
    port, stop_port = _free_port(), _free_port()
    while stop_port == port:
        stop_port = _free_port()
    log = tmp_path / f"{backend}.log"
    async with running_node("sim", *_argv(backend, port, stop_port, extra), log_path=log, ready_timeout_s=60,
                            expect_clean_exit=False) as node:
        ready_port = int(node.ready.get("port", port))
        if backend != "adeptserver":
            await _wait_listening(node.ready.get("host", "127.0.0.1"), stop_port)
        yield Server(backend, node.ready.get("host", "127.0.0.1"), ready_port, log,
                     None if backend == "adeptserver" else stop_port)


@pytest.fixture(params=["python", "vplus"])
def backend(request: pytest.FixtureRequest) -> str:
    return request.param


@pytest.fixture(params=["python", "vplus", "adeptserver"])
def any_backend(request: pytest.FixtureRequest) -> str:
    return request.param


@pytest.fixture
async def server(backend: str, tmp_path: Path) -> AsyncIterator[Server]:
    """A RobotServer backend (protocol version 1 with the extensions) at time scale 1."""
    async with start(backend, tmp_path) as srv:
        yield srv


@pytest.fixture
async def any_server(any_backend: str, tmp_path: Path) -> AsyncIterator[Server]:
    """Any backend, including the AdeptServer-style one (tests of the original protocol subset only)."""
    async with start(any_backend, tmp_path) as srv:
        yield srv


@pytest.fixture
def start_server(tmp_path: Path):
    """``async with start_server(backend, *options) as srv``: a backend started with extra ``aioadept sim``
    options (tests that need a setting of their own)."""
    return lambda backend, *extra: start(backend, tmp_path, *extra)
