"""CURVE on the sim's robot-state stream: only a subscriber holding an allowed key and the sim's public key hears it."""

from __future__ import annotations

import asyncio

import pytest

from aioadept.bus.security import CurveClient, CurveKeyPair, CurveServer
from aioadept.geometry import poses_close
from aioadept.testing.sim import running_sim
from aioadept.vision.virtual_camera import RobotStateFollower

pytestmark = pytest.mark.timeout(20)


async def test_state_stream_with_curve_reaches_only_the_allowed_follower():
    sim_keys, camera_keys, stranger_keys = CurveKeyPair.generate(), CurveKeyPair.generate(), CurveKeyPair.generate()
    server = CurveServer(sim_keys, allowed_clients=[camera_keys.public])
    async with running_sim(instant=True, state_endpoint="tcp://127.0.0.1:0", state_rate_hz=100.0,
                           state_curve=server) as sim:
        allowed = RobotStateFollower(sim.state_endpoint, curve=CurveClient(camera_keys, sim_keys.public)).start()
        stranger = RobotStateFollower(sim.state_endpoint, curve=CurveClient(stranger_keys, sim_keys.public)).start()
        plain = RobotStateFollower(sim.state_endpoint).start()
        try:
            # The sim publishes from this loop; the followers listen in their own threads.
            for _ in range(250):
                await asyncio.sleep(0.02)
                if allowed.received >= 5:
                    break
            await asyncio.sleep(0.3)  # bounded: at 100 Hz a follower let in would have ~30 more samples by now
            here = sim.controller.here
        finally:
            for f in (allowed, stranger, plain):
                f.stop()
    assert allowed.received >= 5
    assert poses_close(allowed.last_state.pose, here, tol_mm=1e-3, tol_deg=1e-3)
    assert stranger.received == 0 and plain.received == 0


def test_command_line_key_files_configure_both_ends(tmp_path):
    import argparse

    from aioadept.bus.security import load_keypair, save_keypair
    from aioadept.cli.sim import build_parser, options_from_args
    from aioadept.vision.service import _state_curve

    sim_pub, sim_sec = save_keypair(tmp_path, "sim")
    cam_pub, cam_sec = save_keypair(tmp_path, "camera")
    opts = options_from_args(build_parser().parse_args(
        ["--state-curve-secret", str(sim_sec), "--state-curve-allow", str(cam_pub)]))
    assert isinstance(opts.state_curve, CurveServer)
    assert opts.state_curve.allowed_clients == frozenset({load_keypair(cam_pub).public})
    with pytest.raises(ValueError, match="needs --state-curve-secret"):
        options_from_args(build_parser().parse_args(["--state-curve-allow", str(cam_pub)]))
    with pytest.raises(ValueError, match="no secret key"):
        options_from_args(build_parser().parse_args(["--state-curve-secret", str(sim_pub)]))

    client = _state_curve(argparse.Namespace(state_curve_secret=str(cam_sec), state_curve_server=str(sim_pub)))
    assert isinstance(client, CurveClient) and client.server_public == load_keypair(sim_pub).public
    assert _state_curve(argparse.Namespace(state_curve_secret=None, state_curve_server=None)) is None
