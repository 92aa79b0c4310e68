"""The robot bridge: several applications share one robot through ``aioadept bridge``.

Real processes on 127.0.0.1: ``aioadept sim`` (the controller), ``aioadept bridge`` (the one TCP writer, a Zenoh
client of this test process, which is the router; multicast scouting off), applications as
:class:`~aioadept.bridge.BridgeClient` s in this process or in a child process that is killed. Each safety rule of
docs/bridge.md has its test here; every test has a hard time cap.
"""

from __future__ import annotations

import asyncio
import importlib.util
import itertools
import os
import signal
import subprocess
import sys
import textwrap
import time
from contextlib import asynccontextmanager

import pytest

from aioadept.commands import Break, Joined, MoveJoints, SetSpeed
from aioadept.errors import AbortedBeforeSend, CommandAborted, ConnectionLost
from aioadept.testing.nodes import running_node

from bustransports import free_port, start_zenoh_router

pytestmark = pytest.mark.skipif(importlib.util.find_spec("zenoh") is None,
                                reason="the [zenoh] extra (eclipse-zenoh) is not installed")

CELL = "bridgetest"
HOME = [0, -90, 180, 0, 90, 0]
FAR = [90, -90, 180, 0, 90, 0]          # 90 deg of J1: ~3.6 s at speed 10
_names = itertools.count()


def slow_move(joints) -> Joined:
    """One batch: speed 10 for the next motion, the motion, and a break that acks when it is done."""
    return Joined(SetSpeed(10), MoveJoints(joints), Break())


@asynccontextmanager
async def shared_robot(tmp_path, *, state: bool = False, sim_killed: bool = False):
    """A sim and a bridge in front of it; yields ``(robot name, sim node, bridge node)``."""
    router = start_zenoh_router()
    name = f"r{next(_names)}-{os.getpid()}"
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0" if state else "none",
                            "--joints", ",".join(map(str, HOME)), log_path=tmp_path / "sim.log",
                            expect_clean_exit=not sim_killed) as sim:
        argv = ["--robot", f"127.0.0.1:{sim.ready['port']}", "--stop-port", sim.ready["stop_port"],
                "--zenoh-connect", router, "--cell", CELL,
                "--name", name, "--log-level", "INFO"]
        if state:
            argv += ["--state-endpoint", sim.ready["state"]]
        async with running_node("bridge", *argv, log_path=tmp_path / "bridge.log",
                                expect_clean_exit=False) as bridge:
            yield name, sim, bridge


def client(name: str, app: str, **kw):
    from aioadept.bridge import BridgeClient

    return BridgeClient(CELL, name, app=app, **kw)


@pytest.mark.timeout(60)
async def test_a_stop_from_one_application_aborts_the_others_motion_in_flight_and_its_queued_one(tmp_path):
    async with shared_robot(tmp_path) as (name, _sim, _bridge):
        async with client(name, "a") as a, client(name, "b") as b:
            moving = asyncio.create_task(b.cmdexec_joined(slow_move(FAR)))        # on the controller
            await asyncio.sleep(0.3)
            queued = asyncio.create_task(b.cmdexec(MoveJoints(HOME)))             # queued in the bridge
            await asyncio.sleep(0.2)
            assert not moving.done() and not queued.done()
            t0 = time.monotonic()
            stop = await a.stop()
            stop_s = time.monotonic() - t0
            with pytest.raises(CommandAborted) as in_flight:
                await asyncio.wait_for(moving, 2)
            with pytest.raises(AbortedBeforeSend, match="stop from application 'a'"):
                await asyncio.wait_for(queued, 2)
            assert stop.ack.ok and stop.skill == "stop"
            assert in_flight.value.ack.status.value == "aborted" and in_flight.value.skill == "break"
            # Stopped part way, and the queued move home never ran: the arm stays where the stop left it.
            p1 = await a.here()
            await asyncio.sleep(0.5)
            p2 = await b.here()
            assert abs(p1.x - p2.x) < 1e-3 and abs(p1.y - p2.y) < 1e-3
            assert abs(stop.ack.pose.y - p2.y) < 1e-3
            home = (await a.cmdexec(MoveJoints(HOME), Break())).pose          # the robot serves again
            assert abs(home.y - p2.y) > 1.0   # p2 was not home: the stop came part way
    assert stop_s < 1.0  # generous: a stop at rest is one hop + a deceleration ramp


@pytest.mark.timeout(60)
async def test_two_applications_with_the_same_ids_never_collide(tmp_path):
    async with shared_robot(tmp_path) as (name, _sim, _bridge):
        async with client(name, "a", id_start=1) as a, client(name, "b", id_start=1) as b:
            ra, rb = await asyncio.gather(*(asyncio.gather(*(c.cmdexec_joined(SetSpeed(40 + k)) for k in range(20)))
                                            for c in (a, b)))
    for results in (ra, rb):
        ids = [r.messages[0].id for r in results]
        assert ids == [f"{n:08x}" for n in range(1, 21)]    # each application sees its own IDs back ...
        assert [r.messages[0].ack.id for r in results] == ids
        assert [r.messages[0].args for r in results] == [(40 + k,) for k in range(20)]   # ... with its own acks


@pytest.mark.timeout(60)
async def test_a_malformed_query_gets_an_error_reply_and_the_bridge_stays_usable(tmp_path):
    from aioadept.errors import BridgeRefused
    from aioadept.bridge.wire import cmd_key
    from aioadept.bus import zenoh as zb

    async with shared_robot(tmp_path) as (name, _sim, _bridge):
        async with client(name, "a") as a:
            loop = asyncio.get_running_loop()

            async def raw(payload: bytes, attachment: bytes | None) -> tuple[bool, bytes]:
                fut = loop.create_future()

                def on_reply(rep):
                    ok = rep.ok is not None
                    data = (rep.ok.payload if ok else rep.err.payload).to_bytes()
                    loop.call_soon_threadsafe(lambda: fut.done() or fut.set_result((ok, data)))

                zb.session().get(cmd_key(CELL, name), zb._zenoh().handlers.Callback(on_reply), payload=payload,
                                 attachment=attachment, timeout=5)
                return await asyncio.wait_for(fut, 5)

            for payload, att, said in ((b"garbage\r\n", b"x", b"line 1"),
                                       (b"0000abcd:here\r\n", None, b"no application name"),
                                       (b"", b"x", b"empty query"),
                                       (b"0000abcd:here\r\n0000abce:stop\r\n", b"x", b"stop travels alone"),
                                       (b"0000abcd:move_to:1,2\r\n\xff", b"x", b"line 2")):
                ok, data = await raw(payload, att)
                assert not ok and data.startswith(b"malformed:") and said in data, data
            assert (await a.here()) is not None
            assert (await a.cmdexec(SetSpeed(30))).messages[0].ack.ok
    assert "malformed query refused" in (tmp_path / "bridge.log").read_text()
    assert BridgeRefused  # the type an application would see (BridgeClient never sends a malformed query)


APP = textwrap.dedent("""
    import asyncio, sys
    from aioadept.bus import zenoh as zb
    from aioadept.bridge import BridgeClient
    from aioadept.commands import Break, Joined, MoveJoints, SetSpeed

    async def main(router, cell, name):
        zb.configure(zb.ZenohOptions.client(router))
        async with BridgeClient(cell, name, app="doomed") as b:
            t1 = asyncio.create_task(b.cmdexec_joined(Joined(SetSpeed(10), MoveJoints({far}), Break())))
            await asyncio.sleep(0.3)
            t2 = asyncio.create_task(b.cmdexec(MoveJoints({home})))
            await asyncio.sleep(0.3)
            print("QUEUED", flush=True)
            await asyncio.gather(t1, t2)
    asyncio.run(main(*sys.argv[1:]))
""")


@pytest.mark.timeout(60)
async def test_a_vanished_application_s_queued_motion_is_never_sent(tmp_path):
    router = start_zenoh_router()
    async with shared_robot(tmp_path) as (name, _sim, _bridge):
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-c", APP.format(far=FAR, home=HOME), router, CELL, name,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        try:
            line = await asyncio.wait_for(proc.stdout.readline(), 20)
            assert line.strip() == b"QUEUED", line
            proc.send_signal(signal.SIGKILL)  # no goodbye: its token goes with its Zenoh link
            await proc.wait()
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
        async with client(name, "watcher") as w:
            # Batches run in arrival order: this answer comes after the doomed app's motion in flight ended ...
            p1 = await w.here(timeout_s=20)
            await asyncio.sleep(0.5)
            p2 = await w.here()
        # ... and the move home it had queued never ran: the arm is at FAR (J1 = 90 deg: y > 0), and at rest.
        assert p1 == p2
        assert p2.y > 300 and abs(p2.x) < 1.0
        await asyncio.sleep(1.0)   # the watcher's token is gone: the bridge has seen it leave
    log = (tmp_path / "bridge.log").read_text()
    assert "application 'doomed' vanished: 1 queued batch(es) dropped, never sent" in log
    assert "application 'watcher' left with nothing queued" in log   # a normal exit: INFO, no warning
    assert "'watcher' vanished" not in log


@pytest.mark.timeout(60)
async def test_the_bridge_dying_fails_every_pending_call_naming_what_is_known_done(tmp_path):
    async with shared_robot(tmp_path) as (name, _sim, bridge):
        async with client(name, "a") as a, client(name, "b") as b:
            call_a = asyncio.create_task(a.cmdexec(SetSpeed(10), Joined(MoveJoints(FAR), Break())))
            await asyncio.sleep(0.5)
            call_b = asyncio.create_task(b.here())     # queued behind a's motion
            await asyncio.sleep(0.2)
            bridge.proc.send_signal(signal.SIGKILL)
            t0 = time.monotonic()
            with pytest.raises(ConnectionLost) as lost_a:
                await asyncio.wait_for(call_a, 5)
            with pytest.raises(ConnectionLost) as lost_b:
                await asyncio.wait_for(call_b, 5)
            gone_s = time.monotonic() - t0
            await bridge.proc.wait()
    assert len(lost_a.value.acked) == 1                      # the set_speed: known done
    assert len(lost_a.value.unresolved) == len(Joined(MoveJoints(FAR), Break()).calls())  # the motion: unknown
    assert lost_a.value.acked[0] not in lost_a.value.unresolved
    assert lost_b.value.acked == () and len(lost_b.value.unresolved) == 1
    assert "robot bridge" in str(lost_a.value) and "robot bridge" in str(lost_b.value)
    assert gone_s < 3.0


@pytest.mark.timeout(60)
async def test_the_robot_state_is_relayed_as_publications(tmp_path):
    from aioadept.bridge.wire import state_key
    from aioadept.bus import Subscriber
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState

    async with shared_robot(tmp_path, state=True) as (name, _sim, bridge):
        assert bridge.ready["state"] == state_key(CELL, name)
        async with Subscriber("zenoh:" + state_key(CELL, name), topics=[ROBOT_STATE_TOPIC]) as sub:
            topic, payload = await asyncio.wait_for(sub.recv(), 10)
    assert topic == ROBOT_STATE_TOPIC
    assert [round(j) for j in RobotState.from_bytes(payload).joints_deg] == HOME


@pytest.mark.timeout(30)
@pytest.mark.parametrize(("argv", "said"), [
    (["--robot", "x:0"], "--robot 'x:0'"),
    (["--stop-port", "many"], "--stop-port 'many'"),
    (["--cell", "a/b"], "--cell 'a/b'"),
    (["--state-endpoint", "zenoh:aioadept/demo/sim/state"], "--state-endpoint"),
    (["--ack-timeout", "0"], "--ack-timeout"),
    (["--zenoh-connect", "udp/1.2.3.4:5"], "udp/1.2.3.4:5"),
    (["--zenoh-listen", "tcp/127.0.0.1:7447", "--zenoh-connect", "tcp/127.0.0.1:7448"], "not both"),
    (["--robot", "127.0.0.1:1", "--zenoh-listen", f"tcp/127.0.0.1:{free_port()}"], "connect to 127.0.0.1:1"),
])
def test_cli_mistakes_are_one_line(argv, said):
    out = subprocess.run([sys.executable, "-m", "aioadept", "bridge", *argv], capture_output=True, text=True,
                         timeout=25)
    assert out.returncode != 0
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("aioadept bridge: ") and said in lines[0], out.stderr


@pytest.mark.timeout(60)
async def test_one_application_cannot_queue_without_bound(tmp_path):
    from aioadept.bridge.wire import MAX_QUEUED_PER_APP
    from aioadept.errors import TooManyPending

    async with shared_robot(tmp_path) as (name, _sim, _bridge):
        async with client(name, "a") as a, client(name, "b") as b:
            moving = asyncio.create_task(b.cmdexec_joined(slow_move(FAR)))
            await asyncio.sleep(0.3)
            extra = 6
            polls = [asyncio.create_task(a.here()) for _ in range(MAX_QUEUED_PER_APP + extra)]
            async with asyncio.timeout(2):   # the refusals come back at once, while the motion runs
                while sum(p.done() for p in polls) < extra:
                    await asyncio.sleep(0.01)
            early = [p for p in polls if p.done()]
            refused = sum(isinstance(p.exception(), TooManyPending) for p in early)
            assert "already has 64 batches" in str(early[0].exception())
            assert not moving.done()
            await b.stop()
            outcomes = await asyncio.gather(*polls, return_exceptions=True)
            with pytest.raises(CommandAborted):
                await moving
            assert (await b.here()) is not None      # b, and the bridge, carry on
    assert refused == extra
    assert sum(isinstance(o, AbortedBeforeSend) for o in outcomes) == MAX_QUEUED_PER_APP
    assert sum(isinstance(o, TooManyPending) for o in outcomes) == extra


@pytest.mark.timeout(60)
async def test_the_paper_s_coroutines_run_unchanged_through_the_bridge_beside_another_application(tmp_path):
    from aioadept.apps.paper import init_move, move_tool_z

    async with shared_robot(tmp_path) as (name, _sim, _bridge):
        async with client(name, "focus") as rc, client(name, "monitor") as mon:
            polls = 0
            running = True

            async def monitor():
                nonlocal polls
                while running:
                    await mon.here()
                    polls += 1

            watcher = asyncio.create_task(monitor())
            try:
                start = (await init_move(rc)).pose
                for _ in range(3):
                    last = (await move_tool_z(rc, 20, 2.5)).pose
                final = await rc.here()
            finally:
                running = False
                await watcher
    moved = ((final.x - start.x) ** 2 + (final.y - start.y) ** 2 + (final.z - start.z) ** 2) ** 0.5
    assert abs(moved - 7.5) < 0.05            # three 2.5 mm steps along the tool's z
    assert last is not None and polls > 0     # the other application was served meanwhile


@pytest.mark.timeout(60)
async def test_a_lost_controller_link_names_what_is_known_done_and_queued_batches_are_not_sent(tmp_path):
    async with shared_robot(tmp_path, sim_killed=True) as (name, sim, _bridge):
        async with client(name, "a") as a, client(name, "b") as b:
            batch = slow_move(FAR)
            moving = asyncio.create_task(b.cmdexec_joined(batch))
            await asyncio.sleep(0.5)
            queued = asyncio.create_task(a.here())
            await asyncio.sleep(0.2)
            sim.proc.send_signal(signal.SIGKILL)
            with pytest.raises(ConnectionLost) as lost:
                await asyncio.wait_for(moving, 5)
            with pytest.raises(ConnectionLost) as not_sent:
                await asyncio.wait_for(queued, 10)
            await sim.proc.wait()
    n = len(batch.calls())
    # set_speed and the move were acked (forward processing: a move acks as it starts); the breaks are unknown.
    assert len(lost.value.acked) == 2 and len(lost.value.unresolved) == n - 2
    assert "controller link lost" in str(lost.value)
    # Never acked. Normally never sent either (the reconnect is refused); but a controller process still dying can
    # accept the reconnect into its listen backlog and then reset it: then it was sent, and it says so.
    assert not_sent.value.acked == ()
    said = str(not_sent.value)
    assert ("not sent" in said and not_sent.value.unresolved == ()) or (
        len(not_sent.value.unresolved) == 1 and said.count("acked=") == 1), said


@pytest.mark.timeout(90)
async def test_the_bridge_serves_the_vplus_emulated_server_too(tmp_path):
    from pathlib import Path

    router = start_zenoh_router()
    vplus = Path(__file__).resolve().parents[2] / "vplus"
    files = [str(vplus / f) for f in ("rsconfig.V2", "rserver.V2", "rsskills.V2")]
    name = f"v{next(_names)}-{os.getpid()}"
    async with running_node("sim", "--vplus", *files, "--run", "rs.main", "--map-port", "1234=0",
                            "--map-port", "1235=0", "--state-endpoint", "none", log_path=tmp_path / "vplus.log",
                            expect_clean_exit=False) as server:
        argv = ["--robot", f"127.0.0.1:{server.ready['port']}", "--zenoh-connect", router, "--cell", CELL,
                "--name", name]
        if server.ready.get("stop_port"):
            argv += ["--stop-port", server.ready["stop_port"]]
        async with running_node("bridge", *argv, log_path=tmp_path / "bridge.log", expect_clean_exit=False):
            async with client(name, "a") as a, client(name, "b") as b:
                moving = asyncio.create_task(b.cmdexec_joined(slow_move(FAR)))
                await asyncio.sleep(0.5)
                queued = asyncio.create_task(b.cmdexec(MoveJoints(HOME)))
                await asyncio.sleep(0.2)
                stop = await a.stop()
                with pytest.raises(CommandAborted):
                    await asyncio.wait_for(moving, 5)
                with pytest.raises(AbortedBeforeSend):
                    await asyncio.wait_for(queued, 5)
                p1 = await a.here()
                await asyncio.sleep(0.5)
                p2 = await a.here()
    assert stop.ack.ok
    assert abs(p1.y - p2.y) < 1e-3 and abs(p2.y - stop.ack.pose.y) < 1e-3
