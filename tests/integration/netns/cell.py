"""The simulated cell run across the two-network topology (see ``topology.py`` and docs/topology.md).

- ROB: ``aioadept sim`` bound to the robot-net address; its TCP server only accepts MCN's robot-net address
  (``--allow``), its state PUB is bound on the robot net.
- MCN: the state relay (``state_relay.py``: robot-net SUB -> vision-net PUB), then ``aioadept focus``, which talks
  TCP to ROB and ZeroMQ to VIS.
- VIS: ``aioadept vision`` with the virtual camera, following the robot state through the relay on MCN.

Every process is started with ``ip netns exec NS <python> ...``, waited for on its ``READY`` line, and stopped
(SIGINT, then SIGTERM, then SIGKILL) on the way out, also when something fails.
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

from aioadept.apps.processes import NodeProcess

try:
    from .topology import Topology, forwarding, set_forwarding
except ImportError:  # run as a plain module path (scripts/netns_cell.py)
    from topology import Topology, forwarding, set_forwarding  # type: ignore[no-redef]

HERE = Path(__file__).resolve().parent
PROBE = str(HERE / "probe.py")
RELAY = str(HERE / "state_relay.py")


class NsNode(NodeProcess):
    """A :class:`NodeProcess` whose command line is given whole (here: prefixed with ``ip netns exec NS``)."""

    def __init__(self, name: str, argv: list[str], **kw: Any) -> None:
        super().__init__(name, [], **kw)
        self.argv = argv


def _aioadept(topo: Topology, ns: str, *args: str) -> list[str]:
    return topo.exec_argv(ns, [sys.executable, "-m", "aioadept", *args])


async def probe(topo: Topology, ns: str, kind: str, *args: str) -> dict[str, Any]:
    """Run ``probe.py`` inside ``ns``; its JSON result, with the namespace role added."""
    proc = await asyncio.create_subprocess_exec(*topo.exec_argv(ns, [sys.executable, PROBE, kind, *args]),
                                                stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    out, err = await proc.communicate()
    if proc.returncode != 0:
        raise RuntimeError(f"probe {kind} {args} in {ns} failed ({proc.returncode}): {err.decode()}")
    res = json.loads(out)
    role = {topo.rob: "ROB", topo.mcn: "MCN", topo.vis: "VIS"}[ns]
    return {"from": role, **res}


async def reachability(topo: Topology, *, sim_port: int, vis_port: int, timeout_s: float = 1.0) -> dict[str, Any]:
    """The probes. ``across``: between the nets (must fail); ``controls``: to MCN and from MCN (must succeed, so the
    failures are not a dead link or a closed port); ``bridged``: ROB -> VIS while MCN forwards for a moment (must
    succeed, so the probes would see a bridge; forwarding is off again before ``across`` runs)."""
    t = str(timeout_s)
    set_forwarding(topo, True)
    try:
        bridged = await asyncio.gather(probe(topo, topo.rob, "tcp", topo.vis_addr, str(vis_port), "5"),
                                       probe(topo, topo.rob, "ping", topo.vis_addr, "5"))
    finally:
        set_forwarding(topo, False)
    across = [
        probe(topo, topo.rob, "tcp", topo.vis_addr, str(vis_port), t),
        probe(topo, topo.rob, "ping", topo.vis_addr, t),
        probe(topo, topo.vis, "tcp", topo.rob_addr, str(sim_port), t),
        probe(topo, topo.vis, "ping", topo.rob_addr, t),
    ]
    controls = [
        probe(topo, topo.rob, "ping", topo.mcn_rob_addr, "5"),
        probe(topo, topo.vis, "ping", topo.mcn_vis_addr, "5"),
        probe(topo, topo.mcn, "tcp", topo.rob_addr, str(sim_port), "5"),
        probe(topo, topo.mcn, "tcp", topo.vis_addr, str(vis_port), "5"),
    ]
    results = await asyncio.gather(*across, *controls)
    return {"bridged": list(bridged), "across": results[:len(across)], "controls": results[len(across):],
            "mcn_ip_forward_after": forwarding(topo)}


async def run_cell(topo: Topology, workdir: Path, *, time_scale: float = 20.0, speed: int = 25,
                   delta_z_mm: float = 2.0, focus_offset_mm: float = 20.0, seed: int = 5,
                   focus_timeout_s: float = 60.0, say: Any = None) -> dict[str, Any]:
    """Start the nodes in their namespaces, probe reachability, run the focus app in MCN; return a report."""
    say = say or (lambda _msg: None)
    logs = workdir / "logs"
    report: dict[str, Any] = {
        "namespaces": {"ROB": topo.rob, "MCN": topo.mcn, "VIS": topo.vis},
        "addresses": {"ROB": topo.rob_addr, "MCN": [topo.mcn_rob_addr, topo.mcn_vis_addr], "VIS": topo.vis_addr},
        "mcn_ip_forward": forwarding(topo),
        "commands": {},
    }
    nodes: dict[str, NodeProcess] = {}
    relay_stats = workdir / "relay-stats.json"
    async with contextlib.AsyncExitStack() as stack:
        async def start(name: str, argv: list[str]) -> dict[str, str]:
            node = NsNode(name, argv, log_path=logs / f"{name}.log", ready_timeout_s=30.0)
            report["commands"][name] = shlex.join(argv)
            say(f"$ {shlex.join(argv)}")
            await stack.enter_async_context(node)
            nodes[name] = node
            say(f"  {name}: READY {' '.join(f'{k}={v}' for k, v in node.ready.items())}")
            return node.ready

        sim = await start("sim", _aioadept(
            topo, topo.rob, "sim", "--host", topo.rob_addr, "--port", "0", "--time-scale", f"{time_scale:g}",
            "--state-endpoint", f"tcp://{topo.rob_addr}:0", "--insecure", "--allow", topo.mcn_rob_addr))
        relay = await start("relay", topo.exec_argv(topo.mcn, [
            sys.executable, RELAY, "--sub", sim["state"], "--pub", f"tcp://{topo.mcn_vis_addr}:0",
            "--stats", str(relay_stats)]))
        vis = await start("vision", _aioadept(
            topo, topo.vis, "vision", "--state-endpoint", relay["pub"],
            "--request-endpoint", f"tcp://{topo.vis_addr}:0", "--response-endpoint", f"tcp://{topo.vis_addr}:0",
            "--insecure", "--policy", "after", "--seed", str(seed), "--focus-offset-mm", f"{focus_offset_mm:g}"))
        report["endpoints"] = {"robot": f"{sim['host']}:{sim['port']}", "state": sim["state"],
                               "state_relayed": relay["pub"], "vision_request": vis["request"],
                               "vision_response": vis["response"]}

        vis_port = int(vis["request"].rsplit(":", 1)[1])
        t0 = time.monotonic()
        report["reachability"] = await reachability(topo, sim_port=int(sim["port"]), vis_port=vis_port)
        report["reachability_s"] = round(time.monotonic() - t0, 2)
        for group in ("bridged", "across", "controls"):
            for r in report["reachability"][group]:
                say(f"  probe [{group}] {r['from']} -> {r['target']} ({r['kind']}): "
                    f"{'reachable' if r['reachable'] else 'UNREACHABLE'} ({r['detail']})")

        out_dir = workdir / "runs"
        focus_argv = _aioadept(topo, topo.mcn, "focus", "--robot", f"{sim['host']}:{sim['port']}",
                               "--request-endpoint", vis["request"], "--response-endpoint", vis["response"],
                               "--speed", str(speed), "--delta-z", f"{delta_z_mm:g}", "--out", str(out_dir),
                               "--no-analyze")
        report["commands"]["focus"] = shlex.join(focus_argv)
        say(f"$ {shlex.join(focus_argv)}")
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
        report["focus_json"] = str(found[-1]) if found else None
        report["focus"] = json.loads(found[-1].read_text()) if found else None
        say(f"  focus: exit {rc} in {report['focus_s']} s, result {report['focus_json']}")
    # The exit stack has stopped vision, relay and sim (in that order) with SIGINT.
    report["node_exit"] = {name: n.returncode for name, n in nodes.items()}
    report["relayed_messages"] = (json.loads(relay_stats.read_text())["relayed"] if relay_stats.exists()
                                  else None)
    say(f"  nodes stopped: {report['node_exit']}; state messages relayed by MCN: {report['relayed_messages']}")
    return report
