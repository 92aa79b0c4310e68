"""The V+ server's own state stream (vplus/rsstate.V2) on the emulator, relayed by ``aioadept state`` onto the
robot.state topic: the same Protobuf message as the one the emulator's sim side publishes for the same arm, with
joints and pose consistent with ``here``; and the relay reconnects when the controller comes back."""

from __future__ import annotations

import asyncio
from pathlib import Path

import numpy as np
import pytest

from aioadept import EnableAir, Here, MoveToolZ, SetSpeed
from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import Subscriber
from aioadept.client import RobotClient
from aioadept.geometry import poses_close
from aioadept.robots import viper_s850 as kin
from aioadept.testing.nodes import running_node
from aioadept.ports import free_port

VPLUS = Path(__file__).resolve().parents[2] / "vplus"


def off_path_mm(p, a, b) -> float:
    """How far the position of pose ``p`` is from the straight segment between poses ``a`` and ``b`` (mm)."""
    pa = np.array([p.x - a.x, p.y - a.y, p.z - a.z])
    ab = np.array([b.x - a.x, b.y - a.y, b.z - a.z])
    t = float(np.clip(pa @ ab / (ab @ ab), 0.0, 1.0)) if ab @ ab > 0 else 0.0
    return float(np.linalg.norm(pa - t * ab))


def stream_files(tmp_path: Path, *, rate: int = 100) -> list[str]:
    """The shipped modules with the state stream switched on in a copy of rsconfig.V2."""
    cfg = (VPLUS / "rsconfig.V2").read_text()
    assert "rs.stream = FALSE" in cfg and "rs.strate = 100" in cfg
    cfg = cfg.replace("rs.stream = FALSE", "rs.stream = TRUE").replace("rs.strate = 100", f"rs.strate = {rate}")
    (tmp_path / "rsconfig.V2").write_text(cfg)
    return [str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(tmp_path / "rsconfig.V2"),
            str(VPLUS / "rsstate.V2")]


async def next_state(sub: Subscriber, timeout: float = 5.0) -> RobotState:
    return RobotState.from_bytes((await asyncio.wait_for(sub.recv(), timeout))[1])


async def drain(sub: Subscriber) -> None:
    """Drop the samples already queued on ``sub`` (at 100 Hz a new one comes every 10 ms)."""
    while True:
        try:
            await asyncio.wait_for(sub.recv(), 0.002)
        except TimeoutError:
            return


async def until(sub: Subscriber, t_s: float) -> list[RobotState]:
    """The samples up to the first one sampled at server time ``t_s`` or later (included)."""
    out = []
    while not out or out[-1].t_s < t_s:
        out.append(await next_state(sub))
    return out


@pytest.mark.timeout(90)
async def test_relayed_v_plus_stream_matches_the_sims_own_topic_and_here(tmp_path):
    port, sport = free_port(), free_port()
    async with running_node("sim", "--vplus", *stream_files(tmp_path), "--run", "rs.main",
                            "--map-port", f"1234={port}", "--map-port", f"1236={sport}", "--map-port", "1235=0",
                            "--state-endpoint", "tcp://127.0.0.1:0", "--state-rate-hz", "100",
                            log_path=tmp_path / "sim.log", ready_timeout_s=60) as sim:
        async with running_node("state", "--robot", f"127.0.0.1:{sport}", "--state-endpoint", "tcp://127.0.0.1:0",
                                log_path=tmp_path / "relay.log") as relay:
            async with Subscriber(relay.ready["state"], topics=[ROBOT_STATE_TOPIC]) as vsub, \
                       Subscriber(sim.ready["state"], topics=[ROBOT_STATE_TOPIC]) as ssub:
                first = await next_state(vsub, 15.0)      # the relay connects with backoff: allow for it
                own = await next_state(ssub)
                # at rest, at home: the two streams describe the same arm
                assert first.joints_deg == pytest.approx(kin.HOME_JOINTS_DEG, abs=1e-3)
                assert not first.in_motion and first.speed_pct == 100 and not first.air
                assert poses_close(first.pose, own.pose, tol_mm=1e-3, tol_deg=1e-3)
                async with RobotClient("127.0.0.1", port) as robot:
                    await drain(vsub)
                    res = await robot.cmdexec(SetSpeed(30), MoveToolZ(80.0))     # move_rel_tool + break
                    t_rest = res.messages[-1].ack.t_done_s
                    moved = await until(vsub, t_rest)    # the acks' clock is the stream's clock
                    end = await robot.here()
                    await robot.cmdexec(EnableAir())
                    t_air = (await robot.cmdexec(Here())).messages[-1].ack.t_done_s
                # 100 Hz through the emulator: the motion took > 0.3 s, so dozens of samples, some of them moving
                moving = [s for s in moved if s.in_motion]
                assert len(moving) >= 10, [(s.t_s, s.in_motion) for s in moved]
                zs = [s.pose.z for s in moving]
                assert zs == sorted(zs, reverse=True) and zs[0] > end.z
                # every sample's pose is the forward kinematics of its joints (%.3f joints: 0.001 deg is ~0.015 mm).
                # The joints and the pose are two HEREs (rsstate.V2): while the arm moves, the task may be switched
                # between them, so a moving sample's joints are checked to lie on the path between its neighbours
                for prev, s, nxt in zip([moved[0], *moved[:-1]], moved, [*moved[1:], moved[-1]], strict=True):
                    fk = kin.forward(s.joints_deg)
                    if not (s.in_motion or prev.in_motion or nxt.in_motion):
                        assert poses_close(fk, s.pose, tol_mm=0.05, tol_deg=0.01)
                    else:
                        assert off_path_mm(fk, prev.pose, nxt.pose) < 0.05, (fk, prev.pose, s.pose, nxt.pose)
                        assert poses_close(fk, s.pose, tol_mm=1e9, tol_deg=0.01)
                ts = [s.t_s for s in moved]
                assert ts == sorted(ts)
                walls = [s.wall_time_s for s in moved]
                assert walls == sorted(walls)
                rest = (await until(vsub, t_air + 0.02))[-1]
                await drain(ssub)
                own = await next_state(ssub)
                assert not rest.in_motion and rest.air and own.air
                assert poses_close(rest.pose, end, tol_mm=0.002, tol_deg=0.002)        # consistent with `here`
                assert poses_close(rest.pose, own.pose, tol_mm=1e-3, tol_deg=1e-3)      # and with the sim's topic
                assert rest.joints_deg == pytest.approx(own.joints_deg, abs=1e-3)
                # the same clock as the acks, and as the sim's own stream (both count from the server's start)
                assert abs(rest.t_s - own.t_s) < 1.0
                assert abs(rest.wall_time_s - own.wall_time_s) < 1.0


@pytest.mark.timeout(90)
async def test_relay_waits_for_the_controller_and_reconnects_after_a_restart(tmp_path):
    port, sport = free_port(), free_port()
    files = stream_files(tmp_path)

    def sim_args() -> tuple[str, ...]:
        return ("--vplus", *files, "--run", "rs.main", "--map-port", f"1234={port}", "--map-port", f"1236={sport}",
                "--map-port", "1235=0", "--state-endpoint", "none")

    # the relay starts first: nothing listens on the state port yet
    async with running_node("state", "--robot", f"127.0.0.1:{sport}", "--state-endpoint", "tcp://127.0.0.1:0",
                            log_path=tmp_path / "relay.log") as relay:
        async with Subscriber(relay.ready["state"], topics=[ROBOT_STATE_TOPIC]) as sub:
            with pytest.raises(TimeoutError):
                await next_state(sub, 0.5)
            for run in range(2):
                async with running_node("sim", *sim_args(), log_path=tmp_path / f"sim{run}.log", ready_timeout_s=60):
                    st = await next_state(sub, 15.0)
                    assert st.joints_deg == pytest.approx(kin.HOME_JOINTS_DEG, abs=1e-3)
                # the controller is gone: the stream stops (what was queued drains first)
                await drain(sub)
                with pytest.raises(TimeoutError):
                    await next_state(sub, 0.5)
