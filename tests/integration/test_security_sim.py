"""Security defaults of the simulated controller (docs/security.md), checked over real TCP on 127.0.0.1.

- the listener binds loopback unless told otherwise, and an explicit host exposes it;
- the allow-list and the client limit refuse a connection with one SERVER_BUSY error ack, then close it, and
  nothing such a client sends ever runs;
- motion targets beyond a joint limit or out of reach are refused before any motion (pose unchanged);
- the speed cap (``--max-speed``): no motion runs faster, whatever set_speed and the monitor speed ask for.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import sys

import pytest

from aioadept import MoveJoints, MoveRelJoints, MoveRelTool, MoveRelWorld, MoveTo, SetSpeed
from aioadept.client import RobotClient
from aioadept.errors import CommandError, ConnectionLost
from aioadept.geometry import Pose, poses_close
from aioadept.protocol import NO_ID, ErrorCode, LineFramer, Status, parse_ack
from aioadept.cli.sim import build_parser, options_from_args
from aioadept.sim.controller import Controller
from aioadept.sim.server import SimOptions
from aioadept.testing.sim import running_sim


# -- the speed cap -------------------------------------------------------------------------------------------

def motion_time_s(ctl: Controller, speed: int, delta_j1: float) -> tuple[float, float]:
    """(duration of a J1 move at program speed ``speed``, highest effective speed seen), with a fake clock."""
    ctl.connect("c")
    t0 = ctl.now_s + 1.0
    j = list(ctl.joints_at(t0))
    j[0] += delta_j1
    out = ctl.handle(f"0000000a:set_speed:{speed}".encode(), "c", t0)
    out += ctl.handle(("0000000b:move_joints:" + ",".join("%.3f" % v for v in j)).encode(), "c", t0)
    out += ctl.handle(b"0000000c:break", "c", t0)
    assert [(o.ack.id, o.ack.status) for o in out] == [("0000000a", Status.DONE), ("0000000b", Status.DONE)]
    peak = ctl.state(t0 + 0.05).speed_pct
    brk = ctl.step(ctl.next_wake_s())[0].ack
    assert brk.id == "0000000c" and brk.status is Status.DONE
    return brk.t_done_s - t0, peak


def test_speed_cap_limits_every_motion_whatever_set_speed_asks():
    free_fast, peak_fast = motion_time_s(Controller(), 100, 60.0)
    free_slow, _ = motion_time_s(Controller(), 10, 60.0)
    capped, peak_capped = motion_time_s(Controller(max_speed_pct=10), 100, 60.0)
    # Asking 100 % under a 10 % cap moves exactly as asking 10 %: several times slower than uncapped.
    assert capped == pytest.approx(free_slow, rel=1e-9)
    assert capped > 5 * free_fast
    assert peak_capped == pytest.approx(10.0) and peak_fast == pytest.approx(100.0)
    # Below the cap nothing changes; the monitor speed still scales, and the cap bounds the product.
    assert motion_time_s(Controller(max_speed_pct=50), 20, 60.0)[0] == pytest.approx(
        motion_time_s(Controller(), 20, 60.0)[0], rel=1e-9)
    assert motion_time_s(Controller(monitor_speed_pct=50, max_speed_pct=25), 100, 60.0)[1] == pytest.approx(25.0)
    with pytest.raises(ValueError):
        Controller(max_speed_pct=0)


def test_max_speed_cli_option():
    parser = build_parser()
    assert options_from_args(parser.parse_args([])).max_speed_pct == 100.0
    assert options_from_args(parser.parse_args(["--max-speed", "15"])).max_speed_pct == 15.0
    with pytest.raises(ValueError):
        options_from_args(parser.parse_args(["--max-speed", "150"]))


@pytest.mark.timeout(20)
async def test_speed_cap_over_tcp():
    # time_scale speeds motions up for the test; the ratio between capped and uncapped durations is what counts.
    durations = {}
    for cap in (100.0, 20.0):
        async with running_sim(time_scale=20, max_speed_pct=cap) as sim, RobotClient(sim.host, sim.port) as robot:
            res = await robot.cmdexec(SetSpeed(100), MoveJoints([45, -90, 180, 0, 90, 0]))
            brk = res.commands[-1].messages[-1].ack
            move = res.commands[-1].messages[0].ack
            durations[cap] = brk.t_done_s - move.t_done_s
            assert sim.controller.joints_deg[0] == pytest.approx(45.0)
    assert durations[20.0] > 3.5 * durations[100.0]


# -- where the sim listens -------------------------------------------------------------------------------------

def non_loopback_ipv4() -> str | None:
    """An address of this machine outside 127/8, or None (a UDP connect sends nothing, it only picks a route)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(("198.51.100.1", 9))  # TEST-NET-2: any routed address will do
        except OSError:
            return None
        addr = s.getsockname()[0]
    return None if addr.startswith("127.") or addr == "0.0.0.0" else addr


def listening_addresses(port: int) -> set[str]:
    """Local addresses of the sockets in LISTEN state on ``port``, from /proc/net/tcp and tcp6."""
    found = set()
    for path, width in (("/proc/net/tcp", 8), ("/proc/net/tcp6", 32)):
        try:
            rows = open(path).read().splitlines()[1:]
        except OSError:
            continue
        for row in rows:
            local, state = row.split()[1], row.split()[3]
            hexaddr, hexport = local.split(":")
            if state == "0A" and int(hexport, 16) == port:
                raw = bytes.fromhex(hexaddr)
                if width == 8:
                    found.add(socket.inet_ntop(socket.AF_INET, raw[::-1]))
                else:  # four little-endian 32-bit words
                    words = b"".join(raw[i:i + 4][::-1] for i in range(0, 16, 4))
                    found.add(socket.inet_ntop(socket.AF_INET6, words))
    return found


def test_defaults_are_loopback():
    args = build_parser().parse_args([])
    opts = options_from_args(args)
    assert (args.host, opts.host, SimOptions().host) == ("127.0.0.1",) * 3
    assert opts.state_endpoint.startswith("tcp://127.0.0.1:")  # the state stream too


@pytest.mark.timeout(20)
async def test_default_sim_process_listens_on_loopback_only():
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "aioadept.sim", "--port", "0", "--state-endpoint", "none",
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    try:
        ready = (await asyncio.wait_for(proc.stdout.readline(), 15)).decode()  # READY once it listens
        fields = dict(kv.split("=", 1) for kv in ready.split()[1:])
        port = int(fields["port"])
        assert fields["host"] == "127.0.0.1"
        assert listening_addresses(port) == {"127.0.0.1"}
        other = non_loopback_ipv4()
        if other is not None:  # the machine's other address does not lead to the robot
            with pytest.raises(ConnectionRefusedError):
                await asyncio.open_connection(other, port)
    finally:
        proc.terminate()
        await proc.communicate()
    assert proc.returncode == 0


@pytest.mark.timeout(20)
async def test_explicit_host_exposes_the_sim():
    other = non_loopback_ipv4()
    if other is None:
        pytest.skip("this machine has no non-loopback IPv4 address")
    async with running_sim(host=other, instant=True) as sim:
        assert sim.host == other and listening_addresses(sim.port) == {other}
        acks = await exchange(other, sim.port, b"0000e001:here\r\n")
        assert [(a.id, a.status) for a in acks] == [("0000e001", Status.DONE)]
        with pytest.raises(ConnectionRefusedError):  # and then loopback is not served
            await asyncio.open_connection("127.0.0.1", sim.port)


# -- who may connect -----------------------------------------------------------------------------------------

async def exchange(host: str, port: int, data: bytes = b"", *, local: str | None = None,
                   expect_close: bool = False) -> list:
    """Connect (from ``local`` if given), write ``data``, read acks until one per line came back or EOF."""
    reader, writer = await asyncio.open_connection(host, port, local_addr=(local, 0) if local else None)
    framer, acks = LineFramer(1024), []
    try:
        writer.write(data)
        want = data.count(b"\n")
        while expect_close or len(acks) < want:
            try:
                chunk = await reader.read(4096)
            except ConnectionResetError:  # the server closed with our bytes unread: Linux answers RST
                break
            if not chunk:
                break
            acks += [parse_ack(line) for line in framer.feed(chunk)]
    finally:
        writer.close()
        with contextlib.suppress(OSError):
            await writer.wait_closed()
    return acks


def assert_refused(acks: list, reason: str) -> None:
    assert len(acks) == 1, acks
    ack = acks[0]
    assert (ack.id, ack.status, ack.error_code) == (NO_ID, Status.ERROR, ErrorCode.SERVER_BUSY)
    assert reason in ack.error_message


@pytest.mark.timeout(20)
async def test_allow_list_refuses_other_addresses_and_nothing_they_send_runs():
    # All of 127/8 is loopback on Linux, so a second client address needs no network: 127.0.0.2.
    async with running_sim(instant=True, allow=("127.0.0.2",)) as sim:
        home = sim.controller.joints_deg
        acks = await exchange(sim.host, sim.port, expect_close=True)  # from 127.0.0.1: refused, then closed
        assert_refused(acks, "not allowed")
        # A command sent at once, before the refusal is read, never runs either.
        await exchange(sim.host, sim.port, b"0000a001:move_joints:30,-90,180,0,90,0\r\n", expect_close=True)
        assert sim.controller.executed == 0 and sim.controller.joints_deg == home
        assert sim.rejected_total == 2 and sim.connections_total == 0
        # The RobotClient learns it as a lost connection with its command unresolved (it never re-sends).
        with pytest.raises(ConnectionLost) as lost:
            async with RobotClient(sim.host, sim.port, ack_timeout_s=5) as robot:
                await robot.here()
        assert len(lost.value.unresolved) == 1 and sim.controller.executed == 0
        # The allowed address is served.
        acks = await exchange(sim.host, sim.port, b"0000a002:move_joints:30,-90,180,0,90,0\r\n0000a003:break\r\n",
                              local="127.0.0.2")
        assert [(a.id, a.status) for a in acks] == [("0000a002", Status.DONE), ("0000a003", Status.DONE)]
        assert sim.controller.joints_deg[0] == pytest.approx(30.0)


@pytest.mark.timeout(20)
async def test_max_clients_refuses_the_extra_client_and_serves_the_others():
    async with running_sim(instant=True, max_clients=2) as sim, \
            RobotClient(sim.host, sim.port) as a, RobotClient(sim.host, sim.port) as b:
        await a.here()
        await b.here()  # both admitted (each answered)
        assert_refused(await exchange(sim.host, sim.port, expect_close=True), "too many clients")
        executed = sim.controller.executed
        await exchange(sim.host, sim.port, b"0000b001:move_joints:-30,-90,180,0,90,0\r\n", expect_close=True)
        assert sim.controller.executed == executed and sim.controller.joints_deg[0] == pytest.approx(0.0)
        # The admitted clients are unaffected.
        await a.cmdexec(MoveJoints([10, -90, 180, 0, 90, 0]))
        assert poses_close(await b.here(), sim.controller.here, tol_mm=1e-3, tol_deg=1e-3)
        await a.close()
        # A slot frees once the server has seen the close; until then a newcomer is refused (retry, no sleep).
        for _ in range(200):
            acks = await exchange(sim.host, sim.port, b"0000b002:here\r\n", expect_close=False)
            if acks and acks[0].status is Status.DONE:
                break
            assert_refused(acks, "too many clients")
        else:
            pytest.fail("no slot after a client left")
        assert acks[0].id == "0000b002"


# -- motion targets outside the workspace ------------------------------------------------------------------------

@pytest.mark.timeout(20)
async def test_targets_beyond_limits_or_reach_are_refused_before_motion():
    cases = [
        (MoveJoints([171, -90, 180, 0, 90, 0]), ErrorCode.JOINT_LIMIT),      # J1 max 170
        (MoveJoints([0, -90, 180, 0, 90, -361]), ErrorCode.JOINT_LIMIT),     # J6 min -360
        (MoveRelJoints([0, 0, 0, 0, 31, 0]), ErrorCode.JOINT_LIMIT),         # J5 90 -> 121 > 120
        (MoveTo(Pose(2000, 0, 500, 0, 180, 0)), ErrorCode.OUT_OF_REACH),     # reach ~855 mm
        (MoveRelWorld([1000, 0, 0, 0, 0, 0]), ErrorCode.OUT_OF_REACH),
        (MoveRelTool([0, 0, -2000, 0, 0, 0]), ErrorCode.OUT_OF_REACH),
    ]
    # Real-time-ish motion (time_scale 20, not instant): a motion that started would show in the break's times.
    async with running_sim(time_scale=20) as sim, RobotClient(sim.host, sim.port) as robot:
        before_pose, before_joints = await robot.here(), sim.controller.joints_deg
        for command, code in cases:
            with pytest.raises(CommandError) as err:
                await robot.cmdexec(command)  # the move and its break, written together
            assert err.value.code == code, command
            assert err.value.ack.pose == before_pose  # the refusal reports the unchanged pose
            assert sim.controller.joints_deg == before_joints and not sim.controller.trajectory.in_motion(
                sim.now())
            assert await robot.here() == before_pose
        # Still serving: a valid motion runs.
        res = await robot.cmdexec(MoveRelJoints([5, 0, 0, 0, 0, 0]))
        assert sim.controller.joints_deg[0] == pytest.approx(5.0) and res.pose != before_pose
