"""The paper's two-network cell (Fig. 5, "Network topology design") in Linux network namespaces.

ROB (robot net, ``aioadept sim``) and VIS (vision net, ``aioadept vision``) are joined only through MCN, which has
an address on each net and does not forward. The focus application runs in MCN and must complete; ROB and VIS must
not reach each other. The virtual camera gets the robot state through a relay process on MCN (docs/topology.md).

Skipped, with the reason, where namespaces cannot be made (not root, no iproute2, kernel refuses).
Helpers: tests/integration/netns/. The same run with its commands printed: ``scripts/netns_cell.py``.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import pytest

from netns.cell import run_cell
from netns.topology import NetnsUnavailable, cell_topology, create, destroy, list_namespaces, pids_in


@pytest.fixture
def topology():
    try:
        topo = create("aioadept-test")
    except NetnsUnavailable as exc:
        pytest.skip(f"two-network topology test needs network namespaces: {exc}")
    try:
        yield topo
    finally:
        problems = destroy(topo)
        assert not set(topo.namespaces) & set(list_namespaces()), "namespaces left behind"
        assert not problems, problems  # every process was stopped by its owner before the namespaces went


@pytest.mark.timeout(90)
async def test_focus_app_in_mcn_completes_while_robot_and_vision_nets_stay_apart(topology, tmp_path):
    report = await run_cell(topology, tmp_path, time_scale=20.0, speed=25, delta_z_mm=2.0, focus_offset_mm=20.0)
    reach = report["reachability"]
    detail = f"\nreport: {report}"

    # MCN is on both nets and is no router.
    assert report["mcn_ip_forward"] == "0" and reach["mcn_ip_forward_after"] == "0", detail
    # ROB and VIS cannot reach each other: neither TCP to the other's listening port nor ICMP echo...
    assert [(r["from"], r["kind"]) for r in reach["across"]] == [("ROB", "tcp"), ("ROB", "ping"),
                                                                ("VIS", "tcp"), ("VIS", "ping")]
    assert not any(r["reachable"] for r in reach["across"]), detail
    # ...although both reach MCN, MCN reaches both ports, and ROB did reach VIS the moment MCN forwarded: the
    # failures above come from MCN not forwarding, not from a dead link, a closed port or a blind probe.
    assert all(r["reachable"] for r in reach["controls"]), detail
    assert all(r["reachable"] for r in reach["bridged"]), detail

    # The application in MCN completed and found the focal plane (20 mm ahead = step 10 of 2 mm).
    assert report["focus_exit"] == 0, report["focus_log_tail"]
    focus = report["focus"]
    assert focus is not None and "error" not in focus, detail
    assert focus["peak_index"] == 10, focus
    assert focus["peak_offset_mm"] == pytest.approx(20.0)
    assert max(focus["sharpness"]) == focus["sharpness"][10] > 4 * focus["sharpness"][0], focus
    # The virtual camera saw the arm move only through MCN's relay.
    assert report["relayed_messages"] > 0, detail
    assert report["endpoints"]["state_relayed"].startswith(f"tcp://{topology.mcn_vis_addr}:"), detail
    # Every node stopped cleanly on SIGINT.
    assert report["node_exit"] == {"sim": 0, "relay": 0, "vision": 0}, detail


class Boom(Exception):
    pass


@pytest.mark.timeout(30)
def test_namespaces_and_their_processes_are_removed_when_the_body_fails():
    try:
        names = None
        with pytest.raises(Boom):
            with cell_topology("aioadept-test") as topo:
                names = topo.namespaces
                proc = subprocess.Popen(topo.exec_argv(topo.vis, [
                    sys.executable, "-c", "import time; print('READY', flush=True); time.sleep(60)"]),
                    stdout=subprocess.PIPE, text=True)
                assert proc.stdout.readline().strip() == "READY"  # running inside the namespace by now
                assert pids_in(topo.vis) == [proc.pid]
                raise Boom
    except NetnsUnavailable as exc:
        pytest.skip(f"two-network topology test needs network namespaces: {exc}")
    try:
        assert proc.wait(timeout=10) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
        proc.stdout.close()
    assert not set(names) & set(list_namespaces())
