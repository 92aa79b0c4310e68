"""``aioadept vision --curve-secret/--curve-allow`` as a real subprocess: only the listed requester is answered."""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sys
import time

import cv2
import numpy as np
import pytest

from aioadept.bus.communicator import Communicator
from aioadept.bus.security import CurveClient, load_keypair, save_keypair
from aioadept.errors import RequestTimeout


@pytest.mark.timeout(40)
async def test_vision_node_with_curve_answers_only_the_allowed_requester(tmp_path):
    node_pub, node_secret = save_keypair(tmp_path / "keys", "vision")
    mcn_pub, mcn_secret = save_keypair(tmp_path / "keys", "mcn")
    _, stranger_secret = save_keypair(tmp_path / "keys", "stranger")
    folder = tmp_path / "frames"
    folder.mkdir()
    cv2.imwrite(str(folder / "0.png"), np.full((48, 64), 20, np.uint8))
    log = open(tmp_path / "vision.log", "wb")
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "aioadept.vision", "--request-endpoint", "tcp://127.0.0.1:0",
        "--response-endpoint", "tcp://127.0.0.1:0", "--source", f"folder:{folder}", "--graph", "noop",
        "--fps", "30", "--curve-secret", str(node_secret), "--curve-allow", str(mcn_pub),
        stdout=asyncio.subprocess.PIPE, stderr=log)
    try:
        line = (await asyncio.wait_for(proc.stdout.readline(), 30)).decode()
        assert line.startswith("READY"), (line, (tmp_path / "vision.log").read_text())
        ready = dict(f.split("=", 1) for f in line.split()[1:])
        server_public = load_keypair(node_pub).public
        stranger = CurveClient(load_keypair(stranger_secret), server_public=server_public)
        async with Communicator(ready["request"], ready["response"], timeout_s=1.0, curve=stranger) as comm:
            with pytest.raises(RequestTimeout):
                await comm.request("VisionRequest", {"t_request": time.time()})
        async with Communicator(ready["request"], ready["response"], timeout_s=1.0) as comm:  # no CURVE at all
            with pytest.raises(RequestTimeout):
                await comm.request("VisionRequest", {"t_request": time.time()})
        allowed = CurveClient(load_keypair(mcn_secret), server_public=server_public)
        async with Communicator(ready["request"], ready["response"], timeout_s=10.0, curve=allowed) as comm:
            resp = await comm.request("VisionRequest", {"t_request": time.time()})
        assert resp.attributes["sharpness"] == 0.0
    finally:
        if proc.returncode is None:
            proc.send_signal(signal.SIGTERM)
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(5):
                    await proc.wait()
        if proc.returncode is None:
            proc.kill()
            await proc.wait()
        log.close()
    assert (tmp_path / "vision.log").read_text().count("VisionRequest") == 1  # only the allowed one was served
    assert proc.returncode == 0


@pytest.mark.timeout(20)
async def test_vision_curve_options_are_checked(tmp_path):
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "aioadept.vision", "--curve-allow", str(tmp_path / "x.key"),
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    out, err = await proc.communicate()
    assert proc.returncode == 2 and b"READY" not in out and b"--curve-secret" in err
