"""The paper's two-network cell (Fig. 5) as three Linux network namespaces joined by veth pairs.

```
  ROB (robot net host)            MCN (MasterControlNode)             VIS (vision net host)
  rob0 10.231.1.2/24 <--veth--> mcn-rob 10.231.1.1/24
                                 mcn-vis 10.231.2.1/24 <--veth--> vis0 10.231.2.2/24
```

- MCN has one address on each subnet, like the paper's two VLAN adapters, and IPv4/IPv6 forwarding off, so it is
  not a router: nothing passes from one net to the other at the IP level.
- ROB and VIS do get a route to the other subnet *via MCN*. So if ROB cannot reach VIS, the reason is that MCN does
  not forward, not merely that ROB has no route.
- Each namespace has its loopback up. The interfaces are created inside the namespaces (``ip -n``), never in the
  caller's, so their short fixed names cannot clash between runs; the namespace names are unique per run.

Needs root (CAP_SYS_ADMIN + CAP_NET_ADMIN) and iproute2. :func:`why_unavailable` says why not, for a skip message.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field

ROBOT_NET = "10.231.1.0/24"
VISION_NET = "10.231.2.0/24"


class NetnsUnavailable(RuntimeError):
    """This machine cannot create the namespaces (no rights, no iproute2, or the kernel refused)."""


@dataclass(frozen=True)
class Topology:
    rob: str
    mcn: str
    vis: str
    rob_addr: str = "10.231.1.2"
    mcn_rob_addr: str = "10.231.1.1"
    mcn_vis_addr: str = "10.231.2.1"
    vis_addr: str = "10.231.2.2"
    commands: list[str] = field(default_factory=list, compare=False)
    """The ``ip`` commands that built it, in order (for reports)."""

    @property
    def namespaces(self) -> tuple[str, str, str]:
        return (self.rob, self.mcn, self.vis)

    def exec_argv(self, ns: str, argv: list[str]) -> list[str]:
        """``argv`` run inside namespace ``ns`` (``ip netns exec`` execs it: the child's pid is the program's)."""
        return ["ip", "netns", "exec", ns, *argv]


def why_unavailable() -> str | None:
    """None if namespaces can probably be made here, else the reason (for ``pytest.skip``)."""
    if os.name != "posix" or not os.path.isdir("/proc/self/ns"):
        return "network namespaces need Linux"
    if os.geteuid() != 0:
        return "creating network namespaces needs root (run the suite as root to include the topology test)"
    if shutil.which("ip") is None:
        return "iproute2's `ip` command is not installed"
    return None


def _ip(args: list[str], log: list[str]) -> None:
    cmd = ["ip", *args]
    log.append(" ".join(cmd))
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=10)
    if res.returncode != 0:
        raise subprocess.CalledProcessError(res.returncode, cmd, res.stdout, res.stderr)


def create(prefix: str = "aioadept") -> Topology:
    """Build the three namespaces and links; on any failure tear down what exists and raise.

    Raises :class:`NetnsUnavailable` if the very first ``ip netns add`` fails (no rights), ``CalledProcessError``
    for a failure after that.
    """
    reason = why_unavailable()
    if reason:
        raise NetnsUnavailable(reason)
    tag = f"{prefix}-{os.getpid()}-{uuid.uuid4().hex[:6]}"
    topo = Topology(rob=f"{tag}-rob", mcn=f"{tag}-mcn", vis=f"{tag}-vis")
    log = topo.commands
    try:
        _ip(["netns", "add", topo.rob], log)
    except (subprocess.CalledProcessError, OSError) as exc:
        err = getattr(exc, "stderr", "") or str(exc)
        raise NetnsUnavailable(f"`ip netns add` failed: {err.strip()}") from exc
    try:
        _ip(["netns", "add", topo.mcn], log)
        _ip(["netns", "add", topo.vis], log)
        for ns in topo.namespaces:
            _ip(["-n", ns, "link", "set", "lo", "up"], log)
        # The two veth pairs, made inside MCN with the far end moved straight into ROB / VIS.
        _ip(["-n", topo.mcn, "link", "add", "mcn-rob", "type", "veth", "peer", "name", "rob0", "netns", topo.rob],
            log)
        _ip(["-n", topo.mcn, "link", "add", "mcn-vis", "type", "veth", "peer", "name", "vis0", "netns", topo.vis],
            log)
        _ip(["-n", topo.mcn, "addr", "add", f"{topo.mcn_rob_addr}/24", "dev", "mcn-rob"], log)
        _ip(["-n", topo.mcn, "addr", "add", f"{topo.mcn_vis_addr}/24", "dev", "mcn-vis"], log)
        _ip(["-n", topo.rob, "addr", "add", f"{topo.rob_addr}/24", "dev", "rob0"], log)
        _ip(["-n", topo.vis, "addr", "add", f"{topo.vis_addr}/24", "dev", "vis0"], log)
        for ns, dev in ((topo.mcn, "mcn-rob"), (topo.mcn, "mcn-vis"), (topo.rob, "rob0"), (topo.vis, "vis0")):
            _ip(["-n", ns, "link", "set", dev, "up"], log)
        # MCN is not a router (new namespaces start with forwarding off; say so explicitly all the same).
        for key in ("net.ipv4.ip_forward=0", "net.ipv6.conf.all.forwarding=0"):
            _ip(["netns", "exec", topo.mcn, "sysctl", "-q", "-w", key], log)
        # Routes across, via MCN: only MCN's forwarding stands between the nets.
        _ip(["-n", topo.rob, "route", "add", VISION_NET, "via", topo.mcn_rob_addr], log)
        _ip(["-n", topo.vis, "route", "add", ROBOT_NET, "via", topo.mcn_vis_addr], log)
    except BaseException:
        destroy(topo)
        raise
    return topo


def forwarding(topo: Topology) -> str:
    """MCN's ``net.ipv4.ip_forward`` as read inside MCN ("0" or "1")."""
    res = subprocess.run(["ip", "netns", "exec", topo.mcn, "sysctl", "-n", "net.ipv4.ip_forward"],
                         capture_output=True, text=True, timeout=10, check=True)
    return res.stdout.strip()


def set_forwarding(topo: Topology, on: bool) -> None:
    """Turn MCN's IPv4 forwarding on or off (the test turns it on only briefly, to show its probes would see a
    bridged net)."""
    subprocess.run(["ip", "netns", "exec", topo.mcn, "sysctl", "-q", "-w", f"net.ipv4.ip_forward={int(on)}"],
                   capture_output=True, text=True, timeout=10, check=True)


def pids_in(ns: str) -> list[int]:
    res = subprocess.run(["ip", "netns", "pids", ns], capture_output=True, text=True, timeout=10)
    return [int(p) for p in res.stdout.split() if p.isdigit()]


def destroy(topo: Topology) -> list[str]:
    """Kill whatever still runs in the namespaces (by pid: only processes of this run can be in them) and delete
    them; the veth pairs go with them. Never raises; returns the problems it met (expected: none)."""
    problems: list[str] = []
    existing = set(list_namespaces())
    for ns in topo.namespaces:
        if ns not in existing:
            continue
        for pid in pids_in(ns):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, 9)
                problems.append(f"killed leftover pid {pid} in {ns}")
        res = subprocess.run(["ip", "netns", "del", ns], capture_output=True, text=True, timeout=10)
        if res.returncode != 0:
            problems.append(f"ip netns del {ns}: {res.stderr.strip()}")
    return problems


def list_namespaces() -> list[str]:
    res = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True, timeout=10)
    return [line.split()[0] for line in res.stdout.splitlines() if line.strip()]


@contextlib.contextmanager
def cell_topology(prefix: str = "aioadept") -> Iterator[Topology]:
    """``with cell_topology() as topo:`` the namespaces exist; on exit (also on error) they are gone."""
    topo = create(prefix)
    try:
        yield topo
    finally:
        destroy(topo)
