"""The live viewer in a real browser: headless Chromium opens the served Rerun web viewer while a run streams to it.

Chromium is Debian's package (``make test`` installs it when it can; else this test skips and says so), driven over
the Chrome DevTools Protocol with ``websockets``. Every request the page makes to a host other than loopback is
failed (Fetch domain), so the test also shows the viewer needs no internet. The page must load without an
uncaught exception, its canvas must not be blank, and the screenshot is kept under the test's tmp dir (with
``AIOADEPT_UPDATE_FIGURES=1`` also as ``docs/figures/viewer.png``, the README's picture).
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import shutil
import subprocess
import time
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np
import pytest

pytest.importorskip("rerun")
websockets = pytest.importorskip("websockets")

import rerun as rr  # noqa: E402

from aioadept.geometry import Pose  # noqa: E402
from aioadept.record.rrd import CellLogger, default_blueprint  # noqa: E402
from aioadept.record.viewer import ViewerServer  # noqa: E402
from aioadept.robots import viper_s850 as kin  # noqa: E402

CHROMIUM = "/usr/bin/chromium"
FIGURE = Path(__file__).resolve().parents[2] / "docs" / "figures" / "viewer.png"
LOOPBACK = {"127.0.0.1", "localhost", "::1", "[::1]"}

pytestmark = [
    pytest.mark.timeout(150),
    pytest.mark.skipif(not os.access(CHROMIUM, os.X_OK),
                       reason="no /usr/bin/chromium (Debian's chromium package; `make test` installs it as root)"),
]


def _stream_a_run(grpc_url: str) -> None:
    """A short focus run, as the recorder logs it, streamed to the viewer (``AIOADEPT_VIEWER_RRD=run.rrd``: a real
    run's recording instead, which is how the README's picture is made, with ``AIOADEPT_UPDATE_FIGURES=1``)."""
    rec = rr.RecordingStream("aioadept")
    rec.set_sinks(rr.GrpcSink(grpc_url), default_blueprint=default_blueprint())  # as RunRecording streams it
    if os.environ.get("AIOADEPT_VIEWER_RRD"):
        rec.log_file_from_path(os.environ["AIOADEPT_VIEWER_RRD"])
        rec.flush(timeout_sec=30)
        return
    t0 = time.time() - 10.0
    lg = CellLogger(rec, loop_to_epoch_s=t0)
    joints = list(kin.HOME_JOINTS_DEG)
    for i in range(30):
        joints[0] = -3.0 * i
        joints[1] = -90.0 + 2.0 * i
        lg.state(t0 + 0.1 * i, joints, kin.forward(joints))
    pose = kin.forward(joints)
    lg.ack("h", "here", "done", pose, 3.0)
    yy, xx = np.mgrid[0:240, 0:320]
    for i, s in enumerate([10.0, 20.0, 30.0, 25.0]):
        lg.command(f"c{i}", "move_rel_tool", (0, 0, 2.0, 0, 0, 0), 3.1 + i)
        lg.ack(f"c{i}", "move_rel_tool", "done", pose, 3.4 + i)
        lg.request(f"v{i}", "VisionRequest", {}, 3.5 + i)
        lg.response(f"v{i}", "VisionResponse", {"sharpness": s, "frame_t": t0 + 3.49 + i}, 3.6 + i)
        lg.frame((((xx // 20 + yy // 20) % 2) * 200 + 20 * i).astype(np.uint8), t0 + 3.49 + i, step=i)
    lg.mark("retract", 4, 8.0)
    lg.focus_plane(Pose(*pose.as_tuple()), offset_mm=6.0)
    rec.flush()
    rec.disconnect()


async def _cdp_page(port: int, deadline: float) -> str:
    import urllib.request

    while True:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=2) as r:
                pages = [t for t in json.load(r) if t.get("type") == "page"]
            if pages:
                return str(pages[0]["webSocketDebuggerUrl"])
        except OSError:
            pass
        if time.monotonic() > deadline:
            raise TimeoutError("chromium's DevTools endpoint did not come up")
        await asyncio.sleep(0.1)


class Cdp:
    """Minimal DevTools client: send commands, collect events."""

    def __init__(self, ws) -> None:  # noqa: ANN001
        self.ws = ws
        self.n = 0
        self.pending: dict[int, asyncio.Future] = {}
        self.events: list[dict] = []
        self.handlers = []
        self.reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        async for raw in self.ws:
            msg = json.loads(raw)
            if "id" in msg and msg["id"] in self.pending:
                self.pending.pop(msg["id"]).set_result(msg)
            elif "method" in msg:
                self.events.append(msg)
                for h in self.handlers:
                    await h(msg)

    async def send(self, method: str, **params) -> dict:  # noqa: ANN003
        self.n += 1
        fut = asyncio.get_running_loop().create_future()
        self.pending[self.n] = fut
        await self.ws.send(json.dumps({"id": self.n, "method": method, "params": params}))
        msg = await asyncio.wait_for(fut, 30)
        if "error" in msg:
            raise RuntimeError(f"{method}: {msg['error']}")
        return msg.get("result", {})


def _png_to_array(png: bytes) -> np.ndarray:
    import cv2

    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)


async def test_the_served_viewer_loads_offline_and_draws_the_run(tmp_path):
    profile = tmp_path / "chromium-profile"
    with ViewerServer("127.0.0.1", log_path=tmp_path / "viewer.log") as viewer:
        _stream_a_run(viewer.grpc_url)
        proc = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
             "--enable-unsafe-swiftshader", "--disable-background-networking", "--disable-component-update",
             "--disable-sync", "--no-first-run", "--no-default-browser-check", f"--user-data-dir={profile}",
             "--remote-debugging-port=0", "--remote-debugging-address=127.0.0.1", "--window-size=1280,800",
             "about:blank"],
            stdout=subprocess.DEVNULL, stderr=open(tmp_path / "chromium.log", "wb"), start_new_session=True)
        try:
            deadline = time.monotonic() + 30
            port_file = profile / "DevToolsActivePort"
            while not port_file.exists() or not port_file.read_text().strip():
                assert proc.poll() is None, (tmp_path / "chromium.log").read_text()[-2000:]
                assert time.monotonic() < deadline, "chromium did not write DevToolsActivePort"
                await asyncio.sleep(0.1)
            port = int(port_file.read_text().split()[0])
            ws_url = await _cdp_page(port, deadline)
            async with websockets.connect(ws_url, max_size=64 * 2**20) as ws:
                cdp = Cdp(ws)
                blocked: list[str] = []
                requested: list[str] = []

                async def gate(msg: dict) -> None:
                    if msg["method"] != "Fetch.requestPaused":
                        return
                    p = msg["params"]
                    url = p["request"]["url"]
                    requested.append(url)
                    host = urlsplit(url).hostname or ""
                    if url.startswith(("data:", "blob:")) or host in LOOPBACK:
                        asyncio.ensure_future(cdp.send("Fetch.continueRequest", requestId=p["requestId"]))
                    else:
                        blocked.append(url)
                        asyncio.ensure_future(cdp.send("Fetch.failRequest", requestId=p["requestId"],
                                                       errorReason="BlockedByClient"))

                cdp.handlers.append(gate)
                await cdp.send("Fetch.enable", patterns=[{"urlPattern": "*"}])
                await cdp.send("Runtime.enable")
                await cdp.send("Page.enable")
                await cdp.send("Page.navigate", url=viewer.url)
                # Poll: the page loaded, a canvas exists, and the screenshot has content (not one flat colour).
                shot = None
                poll_deadline = time.monotonic() + 90
                while time.monotonic() < poll_deadline:
                    await asyncio.sleep(1.0)
                    r = await cdp.send("Runtime.evaluate", expression="document.querySelectorAll('canvas').length",
                                       returnByValue=True)
                    if not r.get("result", {}).get("value"):
                        continue
                    png = base64.b64decode((await cdp.send("Page.captureScreenshot", format="png"))["data"])
                    img = _png_to_array(png)
                    # The welcome screen or a blank canvas is a few flat colours; the run's views are many.
                    colours = len(np.unique(img.reshape(-1, 3)[::7], axis=0))
                    shot = (png, colours)
                    if colours > 200 and time.monotonic() > poll_deadline - 75:
                        break
                assert shot is not None, "the viewer page never showed a canvas"
                png, colours = shot
                (tmp_path / "viewer.png").write_bytes(png)
                if os.environ.get("AIOADEPT_UPDATE_FIGURES") == "1":  # a test never writes into the checkout
                    shutil.copyfile(tmp_path / "viewer.png", FIGURE)
                exceptions = [e for e in cdp.events if e["method"] == "Runtime.exceptionThrown"]
                cdp.reader.cancel()
            assert colours > 200, f"the canvas looks blank ({colours} colours); screenshot in {tmp_path}"
            assert not exceptions, exceptions[:3]
            assert any(urlsplit(u).port == viewer.web_port for u in requested), requested[:5]
            assert all(urlsplit(u).hostname in LOOPBACK for u in requested if u not in blocked)
        finally:
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)
