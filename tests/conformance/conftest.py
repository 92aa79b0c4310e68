"""One RobotServer conformance suite, run against every backend as a real ``aioadept sim`` subprocess.

Backends (the ``server`` fixture's params):

- ``python``: ``aioadept sim`` with its Python skill table (the default backend);
- ``vplus``: ``aioadept sim --vplus vplus/rserver.V2 vplus/rsskills.V2 vplus/rsconfig.V2 --run rs.main``, the
  shipped V+ server running on the V+ emulator;
- ``adeptserver``: ``examples/vplus/adeptserver_style.V2`` on the emulator, a server in the style of the paper's
  original AdeptServer. It speaks only the original protocol (plain ``done`` acks, no error acks, no stop), so
  only tests marked ``@pytest.mark.adeptserver`` run against it (the ``any_server`` fixture).

Robot models (fixture ``robot_model``, the arm's name; ``arm``: a :class:`modelarm.Arm` giving the tests its joints,
poses and speeds): by default every test runs on the Viper s850, and the tests marked ``@pytest.mark.every_model``
(the ones that exercise what differs between models: motion, limits, here, joint, tool and approach moves) on every
model too. With ``AIOADEPT_CONFORMANCE_MODELS=all`` (``make conformance-models``) every test runs on every model, or
on the models named there (comma-separated). A test that is Viper-only by nature is marked
``@pytest.mark.viper_only`` and says why in its docstring; it runs on the Viper models only. The AdeptServer-style
example knows the Viper s850 only.

The V+ backends need the emulator's ``--vplus`` option; should it ever be missing they are skipped with a loud
reason, never silently. ``--map-port 1234=P`` maps the program's ``FOPEN /LOCAL_PORT 1234`` to a free port P
on 127.0.0.1, and the process prints ``READY ... port=P`` once the program listens; the test connects there.
The stop port (docs/protocol.md 4.2.1) is mapped the same way (``--map-port 1235=Q``; the Python sim:
``--stop-port Q``), so ``Server.stop_port`` is known before the server starts.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from aioadept.protocol import Ack, parse_ack
from aioadept.testing.nodes import running_node
from aioadept.ports import free_port as _free_port
from aioadept.robots import DEFAULT_MODEL, MODELS, model
from modelarm import Arm

ROOT = Path(__file__).resolve().parents[2]
VPLUS_FILES = [str(ROOT / "vplus" / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]
ADEPTSERVER_FILES = [str(ROOT / "examples" / "vplus" / f) for f in ("adeptserver_style.V2",)]
VPLUS_PORT = 1234  # the port both V+ servers FOPEN (rs.config, adeptserver_style)
VPLUS_STOP_PORT = 1235  # the shipped server's stop port (rs.sport)
MODELS_ENV = "AIOADEPT_CONFORMANCE_MODELS"
BACKENDS = ("python", "vplus")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "adeptserver: also runs against the AdeptServer-style V+ example")
    config.addinivalue_line("markers", "every_model: runs on every robot model in the default run too")
    config.addinivalue_line("markers", "viper_only: needs a six-axis Viper (the docstring says why)")


def _models_asked() -> list[str] | None:
    """The models AIOADEPT_CONFORMANCE_MODELS names (``all``: every one), or None when it is not set."""
    text = os.environ.get(MODELS_ENV, "").strip()
    if not text:
        return None
    names = list(MODELS) if text == "all" else [n.strip() for n in text.split(",") if n.strip()]
    for n in names:
        model(n)  # an unknown name fails the collection with the known ones named
    return names


def _models_for(definition: pytest.Function) -> list[str]:
    names = _models_asked()
    if names is None:
        names = list(MODELS) if definition.get_closest_marker("every_model") else [DEFAULT_MODEL]
    if definition.get_closest_marker("viper_only"):
        names = [n for n in names if MODELS[n].family == "viper"]
    return names


def _marked_params(definition: pytest.Function) -> set[str]:
    out: set[str] = set()
    for mark in definition.iter_markers("parametrize"):
        names = mark.args[0]
        out.update(n.strip() for n in (names.split(",") if isinstance(names, str) else names))
    return out


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Parametrise over (backend, robot model): see the module's docstring for which models."""
    wanted = set(metafunc.fixturenames)
    marked = _marked_params(metafunc.definition)
    if "robot_model" not in wanted or "robot_model" in marked:
        return
    models = _models_for(metafunc.definition)
    if "any_backend" in wanted:
        pairs = [(b, n) for b in (*BACKENDS, "adeptserver") for n in models if b != "adeptserver" or n == DEFAULT_MODEL]
        metafunc.parametrize("any_backend,robot_model", pairs, indirect=True, ids=[f"{b}-{n}" for b, n in pairs])
    elif "backend" in wanted and "backend" not in marked:
        pairs = [(b, n) for b in BACKENDS for n in models]
        metafunc.parametrize("backend,robot_model", pairs, indirect=True, ids=[f"{b}-{n}" for b, n in pairs])
    else:
        metafunc.parametrize("robot_model", models, indirect=True)


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


@pytest.fixture
def backend(request: pytest.FixtureRequest) -> str:
    """``python`` or ``vplus`` (parametrised with the robot model by pytest_generate_tests)."""
    return request.param


@pytest.fixture
def any_backend(request: pytest.FixtureRequest) -> str:
    """``python``, ``vplus`` or ``adeptserver`` (parametrised with the robot model by pytest_generate_tests)."""
    return request.param


@pytest.fixture
def robot_model(request: pytest.FixtureRequest) -> str:
    """The name of the robot model the backend runs (pytest_generate_tests: which ones)."""
    return getattr(request, "param", DEFAULT_MODEL)


@pytest.fixture
def arm(robot_model: str) -> Arm:
    """The arm under test: its home, joint targets, work poses and speeds (tests/conformance/modelarm.py)."""
    return Arm.named(robot_model)


def _model_options(name: str) -> tuple[str, ...]:
    return () if name == DEFAULT_MODEL else ("--robot-model", name)


@pytest.fixture
async def server(backend: str, robot_model: str, tmp_path: Path) -> AsyncIterator[Server]:
    """A RobotServer backend (protocol version 1 with the extensions) at time scale 1, serving the robot model."""
    async with start(backend, tmp_path, *_model_options(robot_model)) as srv:
        yield srv


@pytest.fixture
async def any_server(any_backend: str, robot_model: str, tmp_path: Path) -> AsyncIterator[Server]:
    """Any backend, including the AdeptServer-style one (tests of the original protocol subset only)."""
    async with start(any_backend, tmp_path, *_model_options(robot_model)) as srv:
        yield srv


@pytest.fixture
def start_server(robot_model: str, tmp_path: Path):
    """``async with start_server(backend, *options) as srv``: a backend serving the robot model, started with extra
    ``aioadept sim`` options (tests that need a setting of their own)."""
    return lambda backend, *extra: start(backend, tmp_path, *_model_options(robot_model), *extra)
