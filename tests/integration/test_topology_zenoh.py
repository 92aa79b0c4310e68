"""The paper's two-network cell (Fig. 5) redone over Zenoh: a Zenoh router on the MCN, listening
on its address on each net, stands between the robot net and the vision net instead of the ZeroMQ state relay.
The focus application in MCN must complete, with the virtual camera following the robot through the router, while
ROB and VIS still cannot reach each other at the IP level.

Skipped, with the reason, where namespaces cannot be made (not root, no iproute2, kernel refuses) or without the
[zenoh] extra. Helpers: tests/integration/netns/ (cell_zenoh.py, zenoh_router.py); docs/topology.md, "Over Zenoh".
"""

from __future__ import annotations

import importlib.util

import pytest

from netns.cell_zenoh import ZENOH_PORT, run_cell_zenoh
from netns.topology import NetnsUnavailable, create, destroy, list_namespaces

pytestmark = pytest.mark.skipif(importlib.util.find_spec("zenoh") is None,
                                reason="the [zenoh] extra (eclipse-zenoh) is not installed")


@pytest.fixture
def topology():
    try:
        topo = create("aioadept-ztest")
    except NetnsUnavailable as exc:
        pytest.skip(f"two-network topology test needs network namespaces: {exc}")
    try:
        yield topo
    finally:
        problems = destroy(topo)
        assert not set(topo.namespaces) & set(list_namespaces()), "namespaces left behind"
        assert not problems, problems


@pytest.mark.timeout(120)
async def test_focus_in_mcn_completes_through_a_zenoh_router_while_the_nets_stay_apart(topology, tmp_path):
    report = await run_cell_zenoh(topology, tmp_path, time_scale=20.0, speed=25, delta_z_mm=2.0,
                                  focus_offset_mm=20.0)
    reach = report["reachability"]
    detail = f"\nreport: {report}"
    assert report["mcn_ip_forward"] == "0" and reach["mcn_ip_forward_after"] == "0", detail
    assert [(r["from"], r["kind"]) for r in reach["across"]] == [("ROB", "ping"), ("VIS", "tcp"), ("VIS", "ping")]
    assert not any(r["reachable"] for r in reach["across"]), detail
    assert all(r["reachable"] for r in reach["controls"]), detail  # each reaches the router on its own net
    assert all(r["reachable"] for r in reach["bridged"]), detail   # the ping would see a bridge
    # Every stream is a key of the cell through the router: the nodes listen on no bus port of their own.
    assert report["endpoints"]["state"] == "zenoh:aioadept/topo/sim/state", detail
    assert report["endpoints"]["vision_request"] == "zenoh:aioadept/topo/vision/request", detail
    assert f":{ZENOH_PORT}" in report["commands"]["sim"] and topology.mcn_rob_addr in report["commands"]["sim"]
    assert topology.mcn_vis_addr in report["commands"]["vision"]
    # The application in MCN completed; the camera's plane (20 mm = step 10 of 2 mm) proves the camera followed
    # the arm, whose state reached the vision net only through the router.
    assert report["focus_exit"] == 0, report["focus_log_tail"]
    focus = report["focus"]
    assert focus is not None and "error" not in focus, detail
    assert focus["peak_index"] == 10 and focus["peak_offset_mm"] == pytest.approx(20.0), focus
    assert max(focus["sharpness"]) == focus["sharpness"][10] > 4 * focus["sharpness"][0], focus
    assert report["node_exit"] == {"router": 0, "sim": 0, "vision": 0}, detail
