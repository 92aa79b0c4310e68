"""Reachability probes, run inside a namespace: ``ip netns exec NS python probe.py tcp|ping HOST [PORT] TIMEOUT``.

Prints one JSON line ``{"kind": ..., "target": ..., "reachable": bool, "detail": ..., "elapsed_s": ...}`` and exits 0
(2 on bad usage). No external ``ping`` is needed: the ICMP echo is sent on a raw socket (root), so the probe works on
machines without iputils.
"""

from __future__ import annotations

import json
import os
import select
import socket
import struct
import sys
import time


def tcp(host: str, port: int, timeout_s: float) -> tuple[bool, str]:
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            return True, "connected"
    except TimeoutError:
        return False, f"no answer within {timeout_s:g} s"
    except OSError as exc:
        return False, f"{type(exc).__name__}: {exc.strerror or exc}"


def _checksum(data: bytes) -> int:
    if len(data) % 2:
        data += b"\0"
    s = sum(struct.unpack(f"!{len(data) // 2}H", data))
    s = (s >> 16) + (s & 0xFFFF)
    s += s >> 16
    return ~s & 0xFFFF


def ping(host: str, timeout_s: float) -> tuple[bool, str]:
    """One ICMP echo request; reachable if the matching echo reply comes back from ``host`` in time."""
    ident, seq = os.getpid() & 0xFFFF, 1
    payload = b"aioadept-netns-probe"
    header = struct.pack("!BBHHH", 8, 0, 0, ident, seq)
    packet = struct.pack("!BBHHH", 8, 0, _checksum(header + payload), ident, seq) + payload
    try:
        sock = socket.socket(socket.AF_INET, socket.SOCK_RAW, socket.IPPROTO_ICMP)
    except PermissionError as exc:
        return False, f"cannot open a raw ICMP socket: {exc}"
    with sock:
        try:
            sock.sendto(packet, (host, 0))
        except OSError as exc:
            return False, f"{type(exc).__name__}: {exc.strerror or exc}"
        deadline = time.monotonic() + timeout_s
        while (left := deadline - time.monotonic()) > 0:
            if not select.select([sock], [], [], left)[0]:
                break
            data, (src, _) = sock.recvfrom(2048)
            ihl = (data[0] & 0x0F) * 4
            icmp_type, _code, _ck, r_ident, r_seq = struct.unpack("!BBHHH", data[ihl:ihl + 8])
            if icmp_type == 0 and r_ident == ident and r_seq == seq and src == host:
                return True, "echo reply"
            if icmp_type == 3 and data[ihl + 8 + 16:ihl + 8 + 20] == socket.inet_aton(host):
                return False, f"destination unreachable (from {src})"
        return False, f"no echo reply within {timeout_s:g} s"


def main(argv: list[str]) -> int:
    if len(argv) == 4 and argv[0] == "tcp":
        target = f"{argv[1]}:{argv[2]}"
        t0 = time.monotonic()
        ok, detail = tcp(argv[1], int(argv[2]), float(argv[3]))
    elif len(argv) == 3 and argv[0] == "ping":
        target = argv[1]
        t0 = time.monotonic()
        ok, detail = ping(argv[1], float(argv[2]))
    else:
        print(__doc__.split("\n\n")[0], file=sys.stderr)
        return 2
    print(json.dumps({"kind": argv[0], "target": target, "reachable": ok, "detail": detail,
                      "elapsed_s": round(time.monotonic() - t0, 3)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
