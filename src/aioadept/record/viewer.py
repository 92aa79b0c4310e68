"""The live viewer: Rerun's web viewer and its gRPC proxy, served by a ``rerun`` child process on this machine.

``--view`` starts one :class:`ViewerServer` per command: the ``rerun`` executable of the ``rerun-sdk`` wheel, run as
``rerun --serve-web --bind HOST --port GRPC --web-viewer-port WEB``. Each run's :class:`~aioadept.record.RunRecording`
streams to its gRPC proxy; a browser opening :attr:`ViewerServer.url` gets the viewer (HTML + Wasm, shipped in the
wheel: nothing is fetched from the internet) and the data of every run so far.

Choices:

- It binds 127.0.0.1 unless told otherwise: Rerun's own default is every interface, and the stream shows the cell
  (poses, images) to whoever connects, with no authentication (docs/security.md).
- Rerun's usage analytics are off: the child runs with its own configuration folder in which
  ``rerun analytics disable`` was run (the user's own Rerun configuration is neither read nor changed), and with
  ``RERUN_ANALYTICS=0`` in its environment.
- A separate process rather than ``rr.serve_grpc`` in ours: the SDK's servers take no bind address, and the
  viewer's serving work stays off the two cores of the control loop's process.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from aioadept.errors import ViewerUnavailable
from aioadept.record import VIEWER_INSTALL_HINT
from aioadept.ports import free_port

__all__ = ["ViewerServer", "rerun_executable", "viewer_env"]

READY_TIMEOUT_S = 30.0


def rerun_executable() -> str:
    """Path of the ``rerun`` executable of the installed ``rerun-sdk`` (its ``rerun_cli`` package)."""
    try:
        import rerun_cli  # noqa: F401
    except ImportError as exc:
        raise ViewerUnavailable(VIEWER_INSTALL_HINT) from exc
    exe = Path(rerun_cli.__file__).parent / "rerun"
    if exe.is_file() and os.access(exe, os.X_OK):
        return str(exe)
    found = shutil.which("rerun", path=str(Path(sys.executable).parent))
    if found is None:
        raise ViewerUnavailable(f"the rerun executable of rerun-sdk is missing; {VIEWER_INSTALL_HINT}")
    return found


def viewer_env(config_dir: str | os.PathLike[str]) -> dict[str, str]:
    """Environment for a ``rerun`` child: its own config/data folders (analytics disabled there), no analytics."""
    env = dict(os.environ)
    env["XDG_CONFIG_HOME"] = str(Path(config_dir) / "config")
    env["XDG_DATA_HOME"] = str(Path(config_dir) / "data")
    env["XDG_CACHE_HOME"] = str(Path(config_dir) / "cache")
    env["RERUN_ANALYTICS"] = "0"
    return env


def _connectable(host: str) -> str:
    # A server bound to every interface is reached on loopback from here.
    return {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}.get(host, host)  # noqa: S104


def _url_host(host: str) -> str:
    return f"[{host}]" if ":" in host else host


class ViewerServer:
    """A ``rerun --serve-web`` child process bound to ``host`` (default 127.0.0.1), ports picked free.

    ``with ViewerServer() as v: print(v.url)``; :attr:`grpc_url` is what :class:`RunRecording` streams to.
    Raises :class:`ViewerUnavailable` (one line) when the extra is not installed or the viewer does not start.
    """

    def __init__(self, host: str = "127.0.0.1", *, grpc_port: int = 0, web_port: int = 0,
                 memory_limit: str = "1GiB", log_path: str | os.PathLike[str] | None = None) -> None:
        self.host = host
        self.grpc_port = grpc_port
        self.web_port = web_port
        self.memory_limit = memory_limit
        self.log_path = None if log_path is None else Path(log_path)
        self.proc: subprocess.Popen[bytes] | None = None
        self._tmp: tempfile.TemporaryDirectory[str] | None = None
        self._log_file = None

    @property
    def grpc_url(self) -> str:
        return f"rerun+http://{_url_host(_connectable(self.host))}:{self.grpc_port}/proxy"

    @property
    def url(self) -> str:
        """The page to open: the web viewer, told where the stream is."""
        from urllib.parse import quote

        shown = _url_host(_connectable(self.host) if self.host in ("0.0.0.0", "::") else self.host)  # noqa: S104
        proxy = f"rerun+http://{shown}:{self.grpc_port}/proxy"
        return f"http://{shown}:{self.web_port}/?url={quote(proxy, safe='')}"

    def start(self) -> ViewerServer:
        exe = rerun_executable()
        self._tmp = tempfile.TemporaryDirectory(prefix="aioadept-rerun-")
        env = viewer_env(self._tmp.name)
        # The analytics opt-out, written by rerun itself into the child's own configuration folder.
        subprocess.run([exe, "analytics", "disable"], env=env, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, timeout=30, check=False)
        if not self.grpc_port:
            self.grpc_port = free_port(self.host)
        if not self.web_port:
            self.web_port = free_port(self.host)
        argv = [exe, "--serve-web", "--bind", self.host, "--port", str(self.grpc_port),
                "--web-viewer-port", str(self.web_port), "--server-memory-limit", self.memory_limit]
        out = subprocess.DEVNULL
        if self.log_path is not None:
            self.log_path.parent.mkdir(parents=True, exist_ok=True)
            self._log_file = open(self.log_path, "ab")  # noqa: SIM115 - closed in close()
            out = self._log_file
        self.proc = subprocess.Popen(argv, env=env, stdin=subprocess.DEVNULL, stdout=out, stderr=out,
                                     start_new_session=True)
        try:
            self._wait_ready()
        except BaseException:
            self.close()
            raise
        return self

    def _wait_ready(self) -> None:
        host = _connectable(self.host)
        deadline = time.monotonic() + READY_TIMEOUT_S
        pending = {self.grpc_port, self.web_port}
        while pending:
            assert self.proc is not None
            if self.proc.poll() is not None:
                raise ViewerUnavailable(f"the rerun viewer exited at start (code {self.proc.returncode}); "
                                        f"is port {self.grpc_port} or {self.web_port} taken?")
            for port in list(pending):
                with contextlib.suppress(OSError), socket.create_connection((host, port), timeout=0.5):
                    pending.discard(port)
            if pending and time.monotonic() > deadline:
                raise ViewerUnavailable(f"the rerun viewer did not listen on {sorted(pending)} within "
                                        f"{READY_TIMEOUT_S:g} s")
            if pending:
                time.sleep(0.05)

    def close(self) -> None:
        """Stop the child (SIGTERM, then SIGKILL after 5 s) and remove its configuration folder. Idempotent."""
        proc, self.proc = self.proc, None
        if proc is not None and proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    proc.kill()
                proc.wait(5)
        if self._log_file is not None:
            self._log_file.close()
            self._log_file = None
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> ViewerServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
