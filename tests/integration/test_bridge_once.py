"""A command through the bridge runs once: one bridge per robot name, one bridge per query.

Real processes on 127.0.0.1: ``aioadept sim``, ``aioadept bridge`` (Zenoh clients of this test process, the
router), and bridges in child processes. The figure checked is the arm's: an application's ``move_rel_joints`` of
5 deg on J1 must turn J1 by 5 deg, not 10 (two bridges each sending it).
"""

from __future__ import annotations

import asyncio
import math
import os
import subprocess
import sys
import textwrap
from contextlib import asynccontextmanager

import pytest
from test_bridge import CELL, _names, client, shared_robot

from aioadept.commands import Break, MoveRelJoints
from aioadept.testing.nodes import running_node

from bustransports import start_zenoh_router


def _bridge_argv(sim, router: str, name: str) -> list[str]:
    return ["--robot", f"127.0.0.1:{sim.ready['port']}", "--stop-port", sim.ready["stop_port"],
            "--zenoh-connect", router, "--cell", CELL, "--name", name]


async def _spawn(*argv: str) -> asyncio.subprocess.Process:
    return await asyncio.create_subprocess_exec(*argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                                env={**os.environ, "PYTHONUNBUFFERED": "1"})


async def _ready_or_exit(proc: asyncio.subprocess.Process, timeout_s: float = 20.0) -> tuple[bool, str]:
    """``(True, "")`` once the process prints READY; ``(False, stderr)`` if it exits first."""
    async with asyncio.timeout(timeout_s):
        while line := await proc.stdout.readline():
            if line.startswith(b"READY"):
                return True, ""
        await proc.wait()
        return False, (await proc.stderr.read()).decode()


async def _end(proc: asyncio.subprocess.Process) -> None:
    if proc.returncode is None:
        proc.kill()
        await proc.wait()


def _j1(pose) -> float:
    """J1 of the sim's arm from its pose: J1 turns the arm about the base's z (HOME points along +x)."""
    return math.degrees(math.atan2(pose.y, pose.x))


async def _j1_turn(name: str) -> float:
    """How far J1 turns for one application's ``move_rel_joints:5,0,0,0,0,0``."""
    async with client(name, "mover") as app:
        before = await app.here()
        await app.cmdexec_joined(MoveRelJoints([5, 0, 0, 0, 0, 0]), Break(), timeout_s=20)
        await asyncio.sleep(0.3)      # a second bridge's copy would be running now
        await app.cmdexec_joined(Break(), timeout_s=20)
        after = await app.here()
    return _j1(after) - _j1(before)


@pytest.mark.timeout(60)
async def test_a_second_bridge_with_the_same_name_refuses_to_start_and_a_command_runs_once(tmp_path):
    router = start_zenoh_router()
    async with shared_robot(tmp_path) as (name, sim, _bridge):
        second = await _spawn(sys.executable, "-m", "aioadept", "bridge", *_bridge_argv(sim, router, name))
        try:
            served, err = await _ready_or_exit(second)
            turn = await _j1_turn(name)
        finally:
            await _end(second)
    assert not served, "a second bridge with the same name started"
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("aioadept bridge: the robot name ") and "is taken" in lines[0], err
    assert second.returncode not in (0, None)
    assert abs(turn - 5.0) < 0.05, turn


@pytest.mark.timeout(90)
async def test_two_bridges_started_at_the_same_instant_never_both_serve(tmp_path):
    router = start_zenoh_router()
    outcomes = []
    async with running_node("sim", "--port", "0", "--state-endpoint", "none", "--joints", "0,-90,180,0,90,0",
                            log_path=tmp_path / "sim.log") as sim:
        for _ in range(3):
            name = f"t{next(_names)}-{os.getpid()}"
            argv = (sys.executable, "-m", "aioadept", "bridge", *_bridge_argv(sim, router, name))
            procs = list(await asyncio.gather(_spawn(*argv), _spawn(*argv)))
            try:
                results = await asyncio.gather(*(_ready_or_exit(p) for p in procs))
                served = sum(ok for ok, _ in results)
                turn = await _j1_turn(name) if served else None
            finally:
                for p in procs:
                    await _end(p)
            outcomes.append((served, turn, [err for ok, err in results if not ok]))
    for served, turn, errs in outcomes:
        assert served <= 1, outcomes
        assert turn is None or abs(turn - 5.0) < 0.05, outcomes
        for err in errs:    # the refused one says why, in one line
            assert len(err.strip().splitlines()) == 1 and "is taken" in err, err


# A bridge that skips the start check (``NameClaim.take``): what two Zenoh networks joined while each had its bridge
# look like. ``argv``: router cell name port stop_port claim|- ignore_claims(0|1).
FORCED = textwrap.dedent("""
    import asyncio, sys
    from aioadept.bus import zenoh as zb
    from aioadept.bridge import node
    from aioadept.bridge.claim import NameClaim
    from aioadept.client import RobotClient

    async def skipped(self, *args):
        pass

    async def main(router, cell, name, port, stop_port, claim, ignore):
        NameClaim.take = skipped
        if ignore == "1":
            NameClaim._on_claim = lambda self, *a: None
        zb.configure(zb.ZenohOptions.client(router))
        bridge = node.Bridge(RobotClient("127.0.0.1", int(port), stop_port=int(stop_port)), cell=cell, name=name)
        if claim != "-":
            bridge.claim = claim
        async with bridge:
            print("READY", flush=True)
            taken = getattr(bridge, "taken", None)
            await (taken.wait() if taken is not None else asyncio.Event().wait())
            print("TAKEN", bridge.taken_reason, flush=True)
    asyncio.run(main(*sys.argv[1:]))
""")


@asynccontextmanager
async def _forced_bridge(sim, router: str, name: str, claim: str, ignore_claims: bool):
    proc = await _spawn(sys.executable, "-c", FORCED, router, CELL, name, sim.ready["port"], sim.ready["stop_port"],
                        claim, "1" if ignore_claims else "0")
    try:
        served, err = await _ready_or_exit(proc)
        assert served, err
        yield proc
    finally:
        await _end(proc)


@pytest.mark.timeout(60)
async def test_a_query_goes_to_one_bridge_even_when_two_serve_the_name(tmp_path):
    router = start_zenoh_router()
    async with shared_robot(tmp_path) as (name, sim, bridge):
        async with _forced_bridge(sim, router, name, "-", ignore_claims=True):
            await asyncio.sleep(0.5)      # both serve: the forced one's queryable is known to the router
            assert bridge.proc.returncode is None    # the first one (earlier) keeps serving
            turn = await _j1_turn(name)
    assert abs(turn - 5.0) < 0.05, turn


@pytest.mark.timeout(60)
async def test_a_bridge_that_meets_an_earlier_serving_one_stops_serving_in_one_line(tmp_path):
    router = start_zenoh_router()
    async with shared_robot(tmp_path) as (name, sim, bridge):
        async with _forced_bridge(sim, router, name, "0" * 20 + "-00000000", ignore_claims=False) as forced:
            try:
                rc = await asyncio.wait_for(bridge.proc.wait(), 10)
            except TimeoutError:
                rc = None
            turn = await _j1_turn(name)
            assert forced.returncode is None      # the earlier one still serves
    assert rc == 1
    log = (tmp_path / "bridge.log").read_text()
    assert "aioadept bridge: another bridge (claim 00000000000000000000-00000000, started before" in log
    assert abs(turn - 5.0) < 0.05, turn
