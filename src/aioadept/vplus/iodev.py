"""V+ I/O instructions on logical units: ATTACH, DETACH, FOPEN, FCLOSE, READ, WRITE, and the TCP device.

TCP follows the V+ TCP/IP usage of the original AdeptServer (FACTS.md):

- ``ATTACH (lun, 4) "TCP"`` attaches the TCP device; mode 4 picks a free logical unit and returns it in ``lun``.
- ``FOPEN (lun, 16) "/LOCAL_PORT n /CLIENTS k /BUFFER_SIZE b"`` opens a server socket; ``"/REMOTE_IP a.b.c.d
  /REMOTE_PORT n"`` connects as a client. The string is built from the FOPEN items; a number directly after an
  option name (``"/LOCAL_PORT", 1234`` renders as ``/LOCAL_PORT1234``) is read as its value.
- ``READ (lun, handle, mode) $s`` returns the next event: IOSTAT 100 (a client connected, ``handle`` set), 1 (data:
  what has arrived from that client, at most 128 characters; the rest stays for the next READ), 101 (the client
  closed). Mode 0 waits for an event; any other mode returns at once with IOSTAT -526 (*No data received*) if there
  is none.
- ``WRITE (lun, handle) items`` sends the items and CR LF unless the last format is ``/S``.

Sockets are real asyncio sockets bound on the emulator's host (127.0.0.1 by default); ``/LOCAL_PORT n`` binds the
host port that the port map gives for ``n`` (0 = an ephemeral port), and ``Network.on_listen`` reports it.
Connections beyond ``/CLIENTS`` are closed at once, as the controller refuses them.
"""

from __future__ import annotations

import asyncio
import re
from collections import deque
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import Any

from aioadept.vplus import errors as E
from aioadept.vplus.errors import VPlusError

_OPT_RE = re.compile(r"/([A-Za-z_]+)\s*([^/\s]*)")
_READ_MAX = 128
_PAUSE_BYTES = 65536


@dataclass
class Network:
    """Where TCP servers bind: host, the port map (V+ port -> host port), and who hears about bound ports."""

    host: str = "127.0.0.1"
    port_map: dict[int, int] = field(default_factory=dict)
    on_listen: Callable[[int, str, int], None] | None = None
    # WRITEs of the current burst of scheduler rounds, per connection, sent together by flush(): one send for
    # several acks instead of one each (the system call, not the interpreter, dominated pipelined acks)
    pending: dict[asyncio.Transport, list[bytes]] = field(default_factory=dict)
    # fault injection of ``aioadept sim --fault`` (aioadept.sim.server.Faults), on what server connections are
    # written: silent (nothing), ack-delay (each WRITE that much later, order kept), drop-after=N (the connection is
    # closed right after its Nth WRITE is sent: the program then reads IOSTAT 101)
    faults: Any = None
    server_transports: set = field(default_factory=set)   # connections accepted by a /LOCAL_PORT server
    _written: dict[asyncio.Transport, int] = field(default_factory=dict)
    _delayed: dict[asyncio.Transport, deque] = field(default_factory=dict)

    def flush(self) -> None:
        """Send what WRITE queued (the scheduler calls it before it yields to asyncio)."""
        if not self.pending:
            return
        pending, self.pending = self.pending, {}
        for tr, parts in pending.items():
            if not tr.is_closing():
                self._send(tr, parts)

    def _send(self, tr: asyncio.Transport, parts: list[bytes]) -> None:
        f = self.faults
        if f is None or tr not in self.server_transports:
            tr.write(b"".join(parts))
            return
        if f.silent:
            return
        if f.ack_delay_s > 0:
            loop = asyncio.get_running_loop()
            q = self._delayed.setdefault(tr, deque())
            due = loop.time() + f.ack_delay_s
            for p in parts:
                q.append((due, p))
            if len(q) == len(parts):
                loop.call_at(due, self._release_delayed, tr)
            return
        self._out(tr, parts)

    def _release_delayed(self, tr: asyncio.Transport) -> None:
        q = self._delayed.get(tr)
        if not q:
            return
        loop = asyncio.get_running_loop()
        now = loop.time() + 1e-4
        parts = []
        while q and q[0][0] <= now:
            parts.append(q.popleft()[1])
        if parts and not tr.is_closing():
            self._out(tr, parts)
        if q:
            loop.call_at(q[0][0], self._release_delayed, tr)
        else:
            self._delayed.pop(tr, None)

    def _out(self, tr: asyncio.Transport, parts: list[bytes]) -> None:
        drop = self.faults.drop_after
        if drop is None:
            tr.write(b"".join(parts))
            return
        n = self._written.get(tr, 0)
        take = parts[:max(drop - n, 0)]
        if take:
            tr.write(b"".join(take))
        self._written[tr] = n + len(take)
        if n + len(take) >= drop:
            self._written.pop(tr, None)
            tr.close()               # after what is buffered has been sent


class TcpLun:
    """One attached TCP logical unit of a task: a server (several connections) or a client (one)."""

    def __init__(self, rt: Any, task: Any, lun: int) -> None:
        self.rt, self.task, self.lun = rt, task, lun
        self.events: deque[list] = deque()      # [kind, handle, data]
        self.conns: dict[int, asyncio.Transport] = {}
        self.reserved: set[int] = set()          # handles whose 101 the program has not read yet
        self.server: asyncio.base_events.Server | None = None
        self.max_clients = 16
        self.buffered = 0
        self.paused: set[int] = set()
        self.open = False
        self.is_server = False

    def new_handle(self) -> int | None:
        if len(self.conns) >= self.max_clients:
            return None
        h = 0
        while h in self.conns or h in self.reserved:
            h += 1
        return h

    def push(self, kind: int, handle: int, data: str = "") -> None:
        if kind == 1 and self.events and self.events[-1][0] == 1 and self.events[-1][1] == handle:
            self.events[-1][2] += data
        else:
            self.events.append([kind, handle, data])
        if kind == 1:
            self.buffered += len(data)
            if self.buffered > _PAUSE_BYTES and handle in self.conns:
                self.conns[handle].pause_reading()
                self.paused.add(handle)
        self.rt.io_event(self.task)

    def pop(self) -> list | None:
        if not self.events:
            return None
        ev = self.events[0]
        if ev[0] == 1 and len(ev[2]) > _READ_MAX:
            out = [1, ev[1], ev[2][:_READ_MAX]]
            ev[2] = ev[2][_READ_MAX:]
        else:
            out = self.events.popleft()
        if out[0] == 1:
            self.buffered -= len(out[2])
            if self.buffered < _PAUSE_BYTES // 2 and self.paused:
                for h in list(self.paused):
                    tr = self.conns.get(h)
                    if tr is not None:
                        tr.resume_reading()
                self.paused.clear()
        elif out[0] == 101:
            self.reserved.discard(out[1])
        return out

    def close(self) -> None:
        net = self.rt.devices
        if net is not None:
            net.flush()          # what WRITE returned from is sent before the connection goes
        for tr in list(self.conns.values()):
            tr.abort()
        self.conns.clear()
        if self.server is not None:
            self.server.close()
            self.server = None
        self.open = False


class _Proto(asyncio.Protocol):
    def __init__(self, lun: TcpLun) -> None:
        self.lun = lun
        self.handle: int | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        h = self.lun.new_handle()
        if h is None or not self.lun.open:
            transport.close()        # more clients than /CLIENTS: refused
            return
        self.handle = h
        self.lun.conns[h] = transport   # type: ignore[assignment]
        self.lun.reserved.add(h)
        net = self.lun.rt.devices
        if self.lun.is_server and net is not None:
            net.server_transports.add(transport)
        self.lun.push(100, h)

    def data_received(self, data: bytes) -> None:
        if self.handle is not None:
            self.lun.push(1, self.handle, data.decode("latin-1"))

    def connection_lost(self, exc: Exception | None) -> None:
        net = self.lun.rt.devices
        if net is not None and self.handle is not None:
            tr = self.lun.conns.get(self.handle)
            if tr is not None:
                net.server_transports.discard(tr)
                net._written.pop(tr, None)
                net._delayed.pop(tr, None)
        if self.handle is not None and self.lun.conns.get(self.handle) is not None:
            del self.lun.conns[self.handle]
            self.lun.paused.discard(self.handle)
            self.lun.push(101, self.handle)


def _lun_of(T: Any, lun: Any) -> TcpLun | None:
    dev = T.luns.get(int(lun)) if lun is not None else None
    return dev if isinstance(dev, TcpLun) else None


def attach(rt: Any):
    def io_attach(T: Any, refs: tuple, text: tuple) -> Generator:
        if not refs or refs[0] is None:
            if rt.robot is None:
                raise VPlusError(E.ROBOT_NOT_ATTACHED, "*Robot not attached* (the emulator has no robot)")
            rt.robot.attach(T.num)
            T.robot_attached = True
            return
        from aioadept.vplus.builtins import _render

        c, k = refs[0]
        mode = int(refs[1][1]) if len(refs) > 1 and refs[1] is not None else 0
        name = _render(text)[0].strip().upper() if text else ""
        if mode & 4:
            lun = 20
            while lun in T.luns:
                lun += 1
            if c is not None:
                c[k] = float(lun)
        else:
            lun = int(c[k] if c is not None else k)
        if name != "TCP":
            T.iostat[lun] = E.NOT_ATTACHED
            rt.console(T.num, f"*Device not available* {name!r} (the emulator has TCP only)")
            return
        T.luns[lun] = TcpLun(rt, T, lun)
        T.iostat[lun] = 1
        return
        yield  # pragma: no cover

    return io_attach


def _lun_number(refs: tuple) -> int:
    c, k = refs[0]
    return int(c[k] if c is not None else k)


def fopen(rt: Any):
    def io_fopen(T: Any, refs: tuple, text: tuple) -> Generator:
        from aioadept.vplus.builtins import _render

        lun = _lun_number(refs)
        dev = _lun_of(T, lun)
        if dev is None:
            T.iostat[lun] = E.NOT_ATTACHED
            return
        opts = {m.group(1).upper(): m.group(2) for m in _OPT_RE.finditer(_render(text)[0])}
        net = rt.devices
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            loop = None
        if net is None or loop is None:
            T.iostat[lun] = E.DEVICE_ERROR
            rt.console(T.num, "*Device error* TCP needs the emulator in real time (aioadept sim --vplus)")
            return
        try:
            if "LOCAL_PORT" in opts:
                vport = int(float(opts["LOCAL_PORT"]))
                dev.max_clients = int(float(opts.get("CLIENTS") or 16))
                dev.is_server = True
                port = net.port_map.get(vport, vport)
                dev.open = True
                fut = asyncio.ensure_future(loop.create_server(lambda: _Proto(dev), net.host, port))
            elif "REMOTE_PORT" in opts:
                host = opts.get("REMOTE_IP") or net.host
                port = int(float(opts["REMOTE_PORT"]))
                dev.max_clients = 1
                dev.open = True
                fut = asyncio.ensure_future(loop.create_connection(lambda: _Proto(dev), host, port))
            else:
                T.iostat[lun] = E.ILLEGAL_VALUE
                return
        except ValueError:
            T.iostat[lun] = E.ILLEGAL_VALUE
            return
        fut.add_done_callback(lambda f: rt.wake_io(T))
        while not fut.done():
            T.io_wait = True
            yield rt.next_tick()
        exc = fut.exception()
        if exc is not None:
            dev.open = False
            T.iostat[lun] = E.DEVICE_ERROR
            rt.console(T.num, f"*Device error* FOPEN: {exc}")
            return
        if "LOCAL_PORT" in opts:
            dev.server = fut.result()
            real = dev.server.sockets[0].getsockname()[1]
            if net.on_listen is not None:
                net.on_listen(vport, net.host, real)
        T.iostat[lun] = 1

    return io_fopen


def fclose(rt: Any):
    def io_fclose(T: Any, refs: tuple, text: tuple) -> Generator:
        lun = _lun_number(refs)
        dev = _lun_of(T, lun)
        if dev is None:
            T.iostat[lun] = E.NOT_ATTACHED
            return
        dev.close()
        T.iostat[lun] = 1
        return
        yield  # pragma: no cover

    return io_fclose


def detach(rt: Any):
    def io_detach(T: Any, refs: tuple, text: tuple) -> Generator:
        if not refs or refs[0] is None:
            if rt.robot is not None and T.robot_attached:
                rt.robot.detach(T.num)
            T.robot_attached = False
            return
        lun = _lun_number(refs)
        dev = T.luns.pop(lun, None)
        if isinstance(dev, TcpLun):
            dev.close()
        T.iostat[lun] = 1
        return
        yield  # pragma: no cover

    return io_detach


def read(rt: Any):
    def io_read(T: Any, lun: Any, handle: tuple | None, mode: float, targets: tuple) -> Generator:
        n = int(lun)
        dev = _lun_of(T, n)
        if dev is None:
            T.iostat[n] = E.NOT_ATTACHED
            return
        while True:
            ev = dev.pop()
            if ev is not None:
                break
            if mode != 0:
                T.iostat[n] = E.NO_DATA
                return
            T.io_wait = True
            yield rt.next_tick()
        kind, h, data = ev
        if handle is not None:
            handle[0][handle[1]] = float(h)
        for c, k in targets:
            c[k] = data if kind == 1 else ""
        T.iostat[n] = kind

    return io_read


def write(rt: Any):
    def io_write(T: Any, lun: Any, handle: Any, items: tuple) -> Generator:
        from aioadept.vplus.builtins import _render

        n = int(lun)
        dev = _lun_of(T, n)
        if dev is None:
            T.iostat[n] = E.NOT_ATTACHED
            return
        text, no_eol = _render(items)
        if not no_eol:
            text += "\r\n"
        h = int(handle) if handle is not None else (next(iter(dev.conns), -1))
        tr = dev.conns.get(h)
        if tr is None or tr.is_closing():
            T.iostat[n] = E.DEVICE_ERROR
            return
        net = rt.devices
        if net is not None:
            net.pending.setdefault(tr, []).append(text.encode("latin-1"))
        else:
            tr.write(text.encode("latin-1"))
        T.iostat[n] = 1
        # V+ WRITE waits until the record is out: wait while the peer does not read.
        if tr.get_write_buffer_size() > _PAUSE_BYTES:
            if net is not None:
                net.flush()
            while tr.get_write_buffer_size() > _PAUSE_BYTES and not tr.is_closing():
                yield rt.next_tick()

    return io_write


def release_task(rt: Any, T: Any) -> None:
    for dev in list(T.luns.values()):
        if isinstance(dev, TcpLun):
            dev.close()
    T.luns.clear()
