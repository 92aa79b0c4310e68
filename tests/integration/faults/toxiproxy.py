"""toxiproxy (github.com/Shopify/toxiproxy), a real fault-injection TCP proxy, driven over its HTTP API.

    server = find_server()                       # None: not installed -> the cases skip
    with ToxiproxyServer(server) as tp:          # toxiproxy-server on 127.0.0.1, a free API port
        proxy = tp.create_proxy("sim", "127.0.0.1:1234")        # listens on 127.0.0.1:<free port>
        proxy.add_toxic("latency", "downstream", latency=40, jitter=20)

Where the binary is looked for: ``$TOXIPROXY_SERVER`` if set (only there); else ``toxiproxy-server`` on PATH,
the install place of ``scripts/install_toxiproxy.sh`` (``$AIOADEPT_TOOLS_DIR``, default ``~/.cache/aioadept/bin``),
then ``~/go/bin/server`` (what a plain ``go install github.com/Shopify/toxiproxy/v2/cmd/server@v2.5.0`` leaves);
a candidate counts only if its ``-version`` says toxiproxy-server. The API is plain JSON over HTTP, so urllib is enough. Calls block for a millisecond or two; async
tests run them in a thread (``asyncio.to_thread``) so the proxy's traffic to an in-process sim is never stalled.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any
from aioadept.ports import free_port as _free_port

INSTALL_HINT = ("toxiproxy-server not found; build it with scripts/install_toxiproxy.sh "
                "(= go install github.com/Shopify/toxiproxy/v2/cmd/server@v2.5.0) or set TOXIPROXY_SERVER")


def tools_dir() -> Path:
    return Path(os.environ.get("AIOADEPT_TOOLS_DIR") or Path.home() / ".cache" / "aioadept" / "bin")


def _is_toxiproxy(path: str) -> bool:
    try:
        out = subprocess.run([path, "-version"], capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return False
    return "toxiproxy-server" in out.stdout + out.stderr


def find_server() -> str | None:
    """Path of a toxiproxy-server binary, or None. ``$TOXIPROXY_SERVER``, when set, is the only candidate (set it
    empty to run the suite as if toxiproxy were missing)."""
    if "TOXIPROXY_SERVER" in os.environ:
        candidates = [os.environ["TOXIPROXY_SERVER"]]
    else:
        candidates = [shutil.which("toxiproxy-server"), str(tools_dir() / "toxiproxy-server"),
                      str(Path.home() / "go" / "bin" / "server")]
    for c in candidates:
        if c and os.access(c, os.X_OK) and _is_toxiproxy(c):
            return c
    return None


class ToxiproxyError(RuntimeError):
    pass


class Proxy:
    """One proxy: ``host``/``port`` to connect to instead of the upstream."""

    def __init__(self, server: ToxiproxyServer, name: str, listen: str, upstream: str) -> None:
        self.server = server
        self.name = name
        self.host, port = listen.rsplit(":", 1)
        self.port = int(port)
        self.upstream = upstream

    def add_toxic(self, type: str, stream: str = "downstream", *, name: str | None = None,
                  toxicity: float = 1.0, **attributes: Any) -> str:
        """Add a toxic (``latency``, ``bandwidth``, ``reset_peer``, ``slicer``, ...) to ``upstream`` (client to
        server) or ``downstream`` (server to client); it applies to open connections too. Returns its name."""
        body = {"type": type, "stream": stream, "toxicity": toxicity, "attributes": attributes}
        if name:
            body["name"] = name
        return self.server.call("POST", f"/proxies/{self.name}/toxics", body)["name"]

    def remove_toxic(self, name: str) -> None:
        self.server.call("DELETE", f"/proxies/{self.name}/toxics/{name}")

    def toxics(self) -> list[dict[str, Any]]:
        return self.server.call("GET", f"/proxies/{self.name}/toxics")

    def delete(self) -> None:
        self.server.call("DELETE", f"/proxies/{self.name}")


class ToxiproxyServer:
    """``toxiproxy-server`` as a subprocess with its API on 127.0.0.1 (a free port); a context manager."""

    def __init__(self, binary: str, *, log_path: Path | None = None) -> None:
        self.binary = binary
        self.log_path = log_path
        self.api = ""
        self.version = ""
        self.proc: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> ToxiproxyServer:
        for _ in range(3):  # the free port can be taken between our probe and its bind: try another
            port = _free_port()
            log = open(self.log_path, "ab") if self.log_path else subprocess.DEVNULL
            self.proc = subprocess.Popen([self.binary, "-host", "127.0.0.1", "-port", str(port)],
                                         stdout=log, stderr=subprocess.STDOUT)
            if log is not subprocess.DEVNULL:
                log.close()
            self.api = f"http://127.0.0.1:{port}"
            if self._handshake(deadline=time.monotonic() + 10):
                return self
            self._stop()
        raise ToxiproxyError(f"{self.binary} did not start serving its API")

    def _handshake(self, deadline: float) -> bool:
        # toxiproxy prints no READY line with the bound port, so ask its API until it answers (a retry of the
        # same harmless GET; bounded by the deadline, and ends early if the process exits).
        assert self.proc is not None
        delay = 0.005
        while time.monotonic() < deadline and self.proc.poll() is None:
            try:
                with urllib.request.urlopen(self.api + "/version", timeout=1) as resp:
                    self.version = resp.read().decode().strip()
                    return True
            except (urllib.error.URLError, OSError):
                time.sleep(delay)
                delay = min(delay * 2, 0.1)
        return False

    def __exit__(self, *exc: object) -> None:
        self._stop()

    def _stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def call(self, method: str, path: str, body: Any = None) -> Any:
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.api + path, data=data, method=method,
                                     headers={"Content-Type": "application/json"})
        try:
            with urllib.request.urlopen(req, timeout=5) as resp:
                text = resp.read().decode()
        except urllib.error.HTTPError as exc:
            raise ToxiproxyError(f"{method} {path}: {exc.code} {exc.read().decode(errors='replace')}") from exc
        return json.loads(text) if text.strip() else None

    def create_proxy(self, name: str, upstream: str, listen: str = "127.0.0.1:0") -> Proxy:
        """A proxy from ``listen`` (port 0: toxiproxy picks one, reported back) to ``upstream``."""
        got = self.call("POST", "/proxies", {"name": name, "listen": listen, "upstream": upstream,
                                              "enabled": True})
        return Proxy(self, name, got["listen"], upstream)
