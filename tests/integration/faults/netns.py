"""A network namespace on a veth link, to make a real half-open TCP connection.

    with VethNamespace() as ns:        # root side ns.host_ip <--veth--> ns.ns_ip inside namespace ns.name
        ... start a client under ns.exec_prefix, connected to a server on ns.host_ip ...
        ns.cut()                         # the namespace can no longer send anything to ns.host_ip

After :meth:`cut` (a blackhole route inside the namespace), a client there that dies cannot tell the server:
its FIN or RST, and the RST its kernel would answer to later data, are dropped before they leave. The server's
socket stays ESTABLISHED: the peer vanished without FIN, which is what a pulled cable or a crashed host does.

Needs root (CAP_NET_ADMIN and CAP_SYS_ADMIN) and iproute2; :func:`unavailable` says why not, for a skip.
"""

from __future__ import annotations

import os
import shutil
import subprocess


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True, timeout=10)


def unavailable() -> str | None:
    """None if namespaces can be made here, else the reason (for ``pytest.skip``)."""
    if shutil.which("ip") is None:
        return "iproute2 (`ip`) is not installed"
    if os.geteuid() != 0:
        return "network namespaces need root (CAP_NET_ADMIN); run the suite as root or in a privileged container"
    return None


class VethNamespace:
    def __init__(self) -> None:
        tag = os.getpid() % 100_000
        self.name = f"aiofm{tag}"
        self.host_if, self.ns_if = f"fm{tag}r", f"fm{tag}n"       # interface names: at most 15 characters
        net = 10 + tag % 200                                            # 10.232.<net>.0/30, away from the cell's
        self.host_ip, self.ns_ip = f"10.232.{net}.1", f"10.232.{net}.2"
        self.exec_prefix = ("ip", "netns", "exec", self.name)

    def __enter__(self) -> VethNamespace:
        try:
            _ip("netns", "add", self.name)
        except subprocess.CalledProcessError as exc:
            raise PermissionError(f"`ip netns add` failed: {exc.stderr.strip()}") from exc
        try:
            _ip("link", "add", self.host_if, "type", "veth", "peer", "name", self.ns_if, "netns", self.name)
            _ip("addr", "add", f"{self.host_ip}/30", "dev", self.host_if)
            _ip("link", "set", self.host_if, "up")
            _ip("-n", self.name, "addr", "add", f"{self.ns_ip}/30", "dev", self.ns_if)
            _ip("-n", self.name, "link", "set", self.ns_if, "up")
            _ip("-n", self.name, "link", "set", "lo", "up")
        except BaseException:
            self.__exit__()
            raise
        return self

    def cut(self) -> None:
        """Drop everything the namespace sends to the root side (the root side can still send into it)."""
        _ip("-n", self.name, "route", "add", "blackhole", f"{self.host_ip}/32")

    def __exit__(self, *exc: object) -> None:
        # Deleting the namespace deletes the veth pair with it (and the root side's address).
        subprocess.run(["ip", "netns", "del", self.name], capture_output=True, timeout=10)
        subprocess.run(["ip", "link", "del", self.host_if], capture_output=True, timeout=10)
