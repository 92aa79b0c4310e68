"""The two-network cell over Zenoh: a Zenoh router on the MasterControlNode between the namespaces (item 3; docs/topology.md, "Over Zenoh").

- ROB: ``aioadept sim --transport zenoh`` bound to the robot-net address for its TCP server (``--allow`` MCN only),
  a Zenoh client of MCN's robot-net address: its state goes to the router, not to any port of its own.
- MCN: ``zenoh_router.py`` listening on MCN's address on each net; then ``aioadept focus`` with a cell file whose
  ``[bus]`` is Zenoh (``start_router = false``: the router above), talking TCP to ROB and Zenoh to the camera.
- VIS: ``aioadept vision --transport zenoh``, a Zenoh client of MCN's vision-net address; it listens on no port.

The router replaces the ZeroMQ state relay: the virtual camera follows the robot state through it.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import shlex
import sys
import time
from pathlib import Path
from typing import Any

try:
    from .cell import NsNode, _aioadept, probe
    from .topology import Topology, forwarding, set_forwarding
except ImportError:  # run as a plain module path
    from cell import NsNode, _aioadept, probe  # type: ignore[no-redef]
    from topology import Topology, forwarding, set_forwarding  # type: ignore[no-redef]

HERE = Path(__file__).resolve().parent
ROUTER = str(HERE / "zenoh_router.py")
ZENOH_PORT = 7447  # fresh namespaces: nothing else listens there
CELL = "topo"


async def reachability(topo: Topology, *, sim_port: int, timeout_s: float = 1.0) -> dict[str, Any]:
    """``across`` (must fail): ROB and VIS ping each other, VIS connects to the sim's port; ``controls`` (must
    succeed): each reaches the router on MCN's address on its own net, MCN reaches the sim; ``bridged`` (must
    succeed): ROB pings VIS while MCN forwards for a moment (the probe would see a bridge)."""
    t = str(timeout_s)
    set_forwarding(topo, True)
    try:
        bridged = [await probe(topo, topo.rob, "ping", topo.vis_addr, "5")]
    finally:
        set_forwarding(topo, False)
    across = [probe(topo, topo.rob, "ping", topo.vis_addr, t),
              probe(topo, topo.vis, "tcp", topo.rob_addr, str(sim_port), t),
              probe(topo, topo.vis, "ping", topo.rob_addr, t)]
    controls = [probe(topo, topo.rob, "tcp", topo.mcn_rob_addr, str(ZENOH_PORT), "5"),
                probe(topo, topo.vis, "tcp", topo.mcn_vis_addr, str(ZENOH_PORT), "5"),
                probe(topo, topo.mcn, "tcp", topo.rob_addr, str(sim_port), "5")]
    results = await asyncio.gather(*across, *controls)
    return {"bridged": bridged, "across": results[:len(across)], "controls": results[len(across):],
            "mcn_ip_forward_after": forwarding(topo)}


async def run_cell_zenoh(topo: Topology, workdir: Path, *, time_scale: float = 20.0, speed: int = 25,
                         delta_z_mm: float = 2.0, focus_offset_mm: float = 20.0, seed: int = 5,
                         focus_timeout_s: float = 60.0) -> dict[str, Any]:
    """Start the router and the nodes in their namespaces, probe, run the focus app in MCN; return a report."""
    logs = workdir / "logs"
    rob_router, vis_router = f"tcp/{topo.mcn_rob_addr}:{ZENOH_PORT}", f"tcp/{topo.mcn_vis_addr}:{ZENOH_PORT}"
    report: dict[str, Any] = {"mcn_ip_forward": forwarding(topo), "commands": {}}
    nodes: dict[str, NsNode] = {}
    async with contextlib.AsyncExitStack() as stack:
        async def start(name: str, argv: list[str]) -> dict[str, str]:
            node = NsNode(name, argv, log_path=logs / f"{name}.log", ready_timeout_s=30.0)
            report["commands"][name] = shlex.join(argv)
            await stack.enter_async_context(node)
            nodes[name] = node
            return node.ready

        await start("router", topo.exec_argv(topo.mcn, [sys.executable, ROUTER, "--listen", rob_router,
                                                        "--listen", vis_router, "--cell", CELL]))
        zenoh = ["--transport", "zenoh", "--cell", CELL]
        sim = await start("sim", _aioadept(
            topo, topo.rob, "sim", "--host", topo.rob_addr, "--port", "0", "--time-scale", f"{time_scale:g}",
            "--insecure", "--allow", topo.mcn_rob_addr, *zenoh, "--zenoh-connect", rob_router))
        vis = await start("vision", _aioadept(
            topo, topo.vis, "vision", "--policy", "after", "--seed", str(seed),
            "--focus-offset-mm", f"{focus_offset_mm:g}", *zenoh, "--zenoh-connect", vis_router))
        report["endpoints"] = {"robot": f"{sim['host']}:{sim['port']}", "state": sim["state"],
                               "vision_request": vis["request"], "vision_response": vis["response"]}
        report["reachability"] = await reachability(topo, sim_port=int(sim["port"]))

        cell = workdir / "mcn-cell.toml"
        cell.write_text(f'[bus]\ntransport = "zenoh"\ncell = "{CELL}"\nzenoh_router = "{rob_router}"\n'
                        f"start_router = false\n")
        out_dir = workdir / "runs"
        focus_argv = _aioadept(topo, topo.mcn, "focus", "--config", str(cell), "--robot",
                               f"{sim['host']}:{sim['port']}", "--speed", str(speed), "--delta-z", f"{delta_z_mm:g}",
                               "--out", str(out_dir), "--no-analyze", "--no-record")
        report["commands"]["focus"] = shlex.join(focus_argv)
        logs.mkdir(parents=True, exist_ok=True)
        t0 = time.monotonic()
        with open(logs / "focus.log", "wb") as flog:
            proc = await asyncio.create_subprocess_exec(*focus_argv, stdin=asyncio.subprocess.DEVNULL,
                                                        stdout=flog, stderr=asyncio.subprocess.STDOUT)
            try:
                async with asyncio.timeout(focus_timeout_s):
                    rc = await proc.wait()
            finally:
                if proc.returncode is None:
                    proc.kill()
                    await proc.wait()
        report["focus_s"] = round(time.monotonic() - t0, 2)
        report["focus_exit"] = rc
        report["focus_log_tail"] = (logs / "focus.log").read_text(errors="replace")[-3000:]
        found = sorted(out_dir.glob("*/focus.json"))
        report["focus"] = json.loads(found[-1].read_text()) if found else None
    report["node_exit"] = {name: n.returncode for name, n in nodes.items()}
    return report
