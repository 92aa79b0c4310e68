"""V+ I/O instructions on logical units: ATTACH, DETACH, FOPEN, FCLOSE, READ, WRITE, and the TCP device.

A disk LUN (``ATTACH (lun, 4) "DISK"``) is :mod:`aioadept.vplus.disk`'s: READ, WRITE, FCLOSE and DETACH hand it over.

TCP follows the V+ TCP/IP usage of the original AdeptServer (docs/vplus.md, Sources):

- ``ATTACH (lun, 4) "TCP"`` attaches the TCP device; mode 4 picks a free logical unit and returns it in ``lun``.
- ``FOPEN (lun, 16) "/LOCAL_PORT n /CLIENTS k /BUFFER_SIZE b"`` opens a server socket; ``"/REMOTE_IP a.b.c.d
  /REMOTE_PORT n"`` connects as a client. The string is built from the FOPEN items; a number directly after an
  option name (``"/LOCAL_PORT", 1234`` renders as ``/LOCAL_PORT1234``) is read as its value.
- ``READ (lun, handle, mode) $s`` returns the next event: IOSTAT 100 (a client connected, ``handle`` set), 1 (data:
  what has arrived from that client, at most 128 characters; the rest stays for the next READ), 101 (the client
  closed). Mode 0 waits for an event; any other mode returns at once with IOSTAT -526 (*No data received*) if there
  is none. A connection's unread input is held up to ``/BUFFER_SIZE`` bytes (2048 by default); beyond that it is
  not read from the socket (TCP holds the rest), as a controller's buffer would, so one client's backlog ahead of
  another client's stop is at most one buffer.
- ``WRITE (lun, handle) items`` sends the items and CR LF unless the last format is ``/S``. It waits until the
  record is out, as V+ output does (V+ Language User's Guide, "Output Wait Modes", p. 213): here, until the
  connection's output buffer (64 KiB; ``Network.send_buffer`` for small ones) has room, i.e. while the peer does
  not read. A connection that is lost
  meanwhile (the peer reset or closed) ends the wait with an error IOSTAT, never a task blocked for ever.
- ``/N`` (no wait) in a WRITE returns at once; ``IOSTAT(lun, 3)`` is then 0 while that output is not complete,
  1 once it is, negative if it failed. A second WRITE on the same LUN before the first no-wait one completed
  waits for it first, and is cancelled if the first failed (its IOSTAT is then the first's), as the same page
  says "for a particular LUN". UNCONFIRMED whether a controller's TCP server LUN serialises per LUN or per
  client handle: the emulator takes the manual's words, the stricter reading.
- ``FCLOSE (lun, handle)`` on a server LUN closes that one client's connection (reset; the program gets no 101
  for it) and abandons an unfinished no-wait write to it. UNCONFIRMED: no manual page we have shows a handle
  argument to FCLOSE; ``vplus/rsconfig.V2``'s ``rs.closeh`` turns its use off (docs/vplus.md).

Sockets are real asyncio sockets bound on the emulator's host (127.0.0.1 by default); ``/LOCAL_PORT n`` binds the
host port that the port map gives for ``n`` (0 = an ephemeral port), and ``Network.on_listen`` reports it.
Connections beyond ``/CLIENTS`` are closed at once, as the controller refuses them.
"""

from __future__ import annotations

import asyncio
import re
import socket
from collections import deque
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import Any

from aioadept.vplus import errors as E
from aioadept.vplus.disk import DiskLun
from aioadept.vplus.errors import VPlusError
from aioadept.vplus.render import _render

_OPT_RE = re.compile(r"/([A-Za-z_]+)\s*([^/\s]*)")
_READ_MAX = 128
_PAUSE_BYTES = 65536
_DEFAULT_BUFFER = 2048


@dataclass
class Network:
    """Where TCP servers bind: host, the port map (V+ port -> host port), and who hears about bound ports."""

    host: str = "127.0.0.1"
    port_map: dict[int, int] = field(default_factory=dict)
    on_listen: Callable[[int, str, int], None] | None = None
    # a /LOCAL_PORT server that could not bind (port in use, no permission): (V+ port, host, host port, the OS
    # error). The program gets its IOSTAT error, as on a controller; the host may decide more (aioadept.vplus.cli)
    on_bind_error: Callable[[int, str, int, OSError], None] | None = None
    # WRITEs of the current burst of scheduler rounds, per connection, sent together by flush(): one send for
    # several acks instead of one each (the system call, not the interpreter, dominated pipelined acks)
    pending: dict[asyncio.Transport, list[bytes]] = field(default_factory=dict)
    pending_bytes: dict[asyncio.Transport, int] = field(default_factory=dict)   # their sizes, per connection
    # fault injection of ``aioadept sim --fault`` (aioadept.sim.server.Faults), on what server connections are
    # written: silent (nothing), ack-delay (each WRITE that much later, order kept), drop-after=N (the connection is
    # closed right after its Nth WRITE is sent: the program then reads IOSTAT 101)
    faults: Any = None
    server_transports: set = field(default_factory=set)   # connections accepted by a /LOCAL_PORT server
    # ``aioadept sim --tcp-send-buffer BYTES`` (an emulator option for tests): each connection's socket send buffer
    # (SO_SNDBUF) is that small, as a controller's are, and so is the emulator's own output buffer (out_limit), so
    # that a peer that stops reading backs the program's output up after a few KiB instead of the megabytes that
    # the kernel grows a loopback socket's buffer to. None: the OS's buffer and 64 KiB
    send_buffer: int | None = None
    _written: dict[asyncio.Transport, int] = field(default_factory=dict)
    _delayed: dict[asyncio.Transport, deque] = field(default_factory=dict)

    @property
    def out_limit(self) -> int:
        """Bytes a connection's output may hold unread (beyond the socket's buffer) before WRITE waits."""
        return _PAUSE_BYTES if self.send_buffer is None else self.send_buffer

    def flush(self) -> None:
        """Send what WRITE queued (the scheduler calls it before it yields to asyncio)."""
        if not self.pending:
            return
        pending, self.pending = self.pending, {}
        self.pending_bytes.clear()
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
        # unread input per connection: at most /BUFFER_SIZE (the controller's buffer); beyond it the connection is
        # not read (TCP holds the rest), so one client's backlog ahead of another's stop is one buffer, not 64 KiB
        self.inbuf: dict[int, int] = {}
        self.buffer_size = _DEFAULT_BUFFER
        # what the socket delivered beyond that (one read can bring 256 KiB): fed to the program a buffer at a
        # time, each behind the other connections' events, so READ serves the connections in turn
        self.held: dict[int, str] = {}
        self.held_close: set[int] = set()      # a 101 that must wait until that connection's held input is read
        self.open = False
        self.is_server = False
        # the last no-wait WRITE (/N) on this LUN: its connection until its output is complete; its error
        self.nowait: asyncio.Transport | None = None
        self.nowait_err = 0
        self.sent: set[asyncio.Transport] = set()   # connections WRITE sent to at once since the last READ

    def out_bytes(self, tr: asyncio.Transport) -> int:
        """Bytes written to ``tr`` and not yet taken by the OS: the connection's output buffer."""
        net = self.rt.devices
        queued = net.pending_bytes.get(tr, 0) if net is not None else 0
        return tr.get_write_buffer_size() + queued

    def backed_up(self, tr: asyncio.Transport) -> bool:
        """More of what was written to ``tr`` is unread than the emulator's output buffer holds."""
        net = self.rt.devices
        return self.out_bytes(tr) > (_PAUSE_BYTES if net is None else net.out_limit)

    def nowait_state(self) -> int:
        """IOSTAT(lun, 3): 1 the last no-wait output is complete (or there was none), 0 not yet, < 0 it failed."""
        tr = self.nowait
        if tr is None:
            return 1 if self.nowait_err == 0 else self.nowait_err
        if tr.is_closing() or tr not in self.conns.values():
            self.nowait, self.nowait_err = None, E.DEVICE_ERROR   # lost before its output was out
            return self.nowait_err
        if self.backed_up(tr):
            return 0
        self.nowait = None
        return 1

    def close_handle(self, h: int) -> bool:
        """FCLOSE (lun, handle): reset one client's connection; False if there is none with that handle."""
        tr = self.conns.get(h)
        if tr is None:
            return False
        # A peer that reads gets what was written to it, then the end of the connection; one that does not (its
        # output buffer full) is reset: nothing of it is kept for a peer that will not take it.
        reads = not self.backed_up(tr)
        net = self.rt.devices
        if net is not None:
            parts = net.pending.pop(tr, None)
            net.pending_bytes.pop(tr, None)
            if parts and reads and not tr.is_closing():
                tr.write(b"".join(parts))
            net.server_transports.discard(tr)
        del self.conns[h]
        # what it sent and the program has not read goes with it, as its connection does
        kept = [ev for ev in self.events if ev[1] != h]
        self.buffered -= sum(len(ev[2]) for ev in self.events if ev[1] == h and ev[0] == 1)
        self.events = deque(kept)
        self.inbuf.pop(h, None)
        self.held.pop(h, None)
        self.held_close.discard(h)
        if self.nowait is tr:
            self.nowait = None                  # abandoned with the connection, not an error of the LUN
        self.paused.discard(h)
        self.reserved.discard(h)
        if reads:
            tr.close()
        else:
            tr.abort()
        return True

    def drop_input(self, h: int) -> None:
        """Connection ``h`` was reset: its input not yet read by the program is gone with it, as a TCP stack drops
        a reset connection's receive queue. (Kept, a flood's held input, read at once from the socket in 256 KiB,
        took the reader seconds after the flooder was killed, and its slot stayed taken all that time.)"""
        self.held.pop(h, None)
        self.held_close.discard(h)
        mine = [ev for ev in self.events if ev[1] == h and ev[0] == 1]
        if mine:
            self.buffered -= sum(len(ev[2]) for ev in mine)
            self.events = deque(ev for ev in self.events if not (ev[1] == h and ev[0] == 1))
        self.inbuf.pop(h, None)

    def new_handle(self) -> int | None:
        if len(self.conns) >= self.max_clients:
            return None
        h = 0
        while h in self.conns or h in self.reserved:
            h += 1
        return h

    def push(self, kind: int, handle: int, data: str = "") -> None:
        if kind == 1:
            n = self.inbuf.get(handle, 0)
            room = 0 if handle in self.held else max(self.buffer_size - n, 0)
            if len(data) > room:
                self.held[handle] = self.held.get(handle, "") + data[room:]
                data = data[:room]
                tr = self.conns.get(handle)
                if tr is not None and handle not in self.paused:
                    tr.pause_reading()
                    self.paused.add(handle)
                if not data:
                    return
            self.inbuf[handle] = n + len(data)
            self.buffered += len(data)
        elif kind == 101 and handle in self.held:
            self.held_close.add(handle)
            return
        self._append(kind, handle, data)
        self.rt.io_event(self.task)

    def _append(self, kind: int, handle: int, data: str) -> None:
        if kind == 1 and self.events and self.events[-1][0] == 1 and self.events[-1][1] == handle:
            self.events[-1][2] += data
        else:
            self.events.append([kind, handle, data])

    def _release(self, h: int) -> None:
        """Feed connection ``h``'s held input to the program, up to its buffer, behind the others' events."""
        rest = self.held.get(h)
        if rest is None:
            return
        room = self.buffer_size - self.inbuf.get(h, 0)
        take, rest = rest[:room], rest[room:]
        if take:
            self.inbuf[h] = self.inbuf.get(h, 0) + len(take)
            self.buffered += len(take)
            self.events.append([1, h, take])
        if rest:
            self.held[h] = rest
            return
        del self.held[h]
        if h in self.held_close:
            self.held_close.discard(h)
            self.events.append([101, h, ""])
        elif h in self.paused:
            self.paused.discard(h)
            tr = self.conns.get(h)
            if tr is not None:
                tr.resume_reading()

    def pop(self) -> list | None:
        if not self.events:
            return None
        ev = self.events[0]
        if ev[0] == 1 and len(ev[2]) > _READ_MAX:
            out = [1, ev[1], ev[2][:_READ_MAX]]
            ev[2] = ev[2][_READ_MAX:]
            if len(self.events) > 1:
                # the connections are served in turn, a READ each: the rest of this one's input waits behind
                # the others' events (an emulator choice: the manuals do not say; docs/vplus.md)
                self._behind_others()
        else:
            out = self.events.popleft()
        if out[0] == 1:
            self._taken(out[1], len(out[2]))
        elif out[0] == 101:
            self.reserved.discard(out[1])
            self.inbuf.pop(out[1], None)
        return out

    def _taken(self, h: int, n: int) -> None:
        """The program has taken ``n`` characters of connection ``h``'s input: below half its buffer, the rest
        that waits (held, or in the socket) comes in."""
        self.buffered -= n
        left = self.inbuf[h] = self.inbuf.get(h, 0) - n
        if left <= self.buffer_size // 2:
            if h in self.held:
                self._release(h)
            elif h in self.paused:
                self.paused.discard(h)
                tr = self.conns.get(h)
                if tr is not None:
                    tr.resume_reading()

    def byte(self) -> int | None:
        """GETC: the next byte of input (0..255), END_OF_FILE when a connection's end comes first, None when
        nothing has arrived. A connect event in front is taken on the way (its data follows it)."""
        while self.events:
            ev = self.events[0]
            if ev[0] != 1:
                self.pop()
                if ev[0] == 101:
                    return E.END_OF_FILE
                continue
            ch = ev[2][:1]
            if len(ev[2]) <= 1:
                self.events.popleft()
            else:
                ev[2] = ev[2][1:]
            self._taken(ev[1], 1)
            if ch:
                return ord(ch)
        return None

    def _behind_others(self) -> None:
        """Move the first event (the rest of a connection's data), and every later event of that connection, behind
        all other connections' events, in their order. (The rest once stayed in front whenever the connection had
        a later event too, e.g. input released from ``held``: a flood's 2 KiB went out 128 characters a READ, 16
        READs, before another client's stop, 10 ms of a busy reader.)"""
        h = self.events[0][1]
        others = [e for e in self.events if e[1] != h]
        if not others:
            return
        mine: list[list] = []
        for e in self.events:
            if e[1] == h:
                if mine and e[0] == 1 and mine[-1][0] == 1:
                    mine[-1][2] += e[2]          # one data event: a READ takes up to 128 characters of it
                else:
                    mine.append(e)
        self.events = deque(others + mine)

    def close(self, *, graceful: bool = False) -> None:
        """Close the LUN: its connections (``graceful``: each after what it has buffered is sent; else at once,
        a reset) and its server socket."""
        net = self.rt.devices
        if net is not None:
            net.flush()          # what WRITE returned from is sent before the connection goes
        for tr in list(self.conns.values()):
            if graceful:
                tr.close()
            else:
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
        self.transport: asyncio.BaseTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        h = self.lun.new_handle()
        if h is None or not self.lun.open:
            transport.close()        # more clients than /CLIENTS: refused
            return
        self.handle = h
        self.transport = transport
        self.lun.conns[h] = transport   # type: ignore[assignment]
        self.lun.reserved.add(h)
        net = self.lun.rt.devices
        if net is not None and net.send_buffer is not None:
            sock = transport.get_extra_info("socket")
            if sock is not None:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, net.send_buffer)
        if self.lun.is_server and net is not None:
            net.server_transports.add(transport)
        self.lun.push(100, h)

    def data_received(self, data: bytes) -> None:
        if self.handle is not None and self.lun.conns.get(self.handle) is self.transport:
            self.lun.push(1, self.handle, data.decode("latin-1"))

    def connection_lost(self, exc: Exception | None) -> None:
        # Only if the handle is still this connection's: one closed by FCLOSE (lun, handle) has left the table at
        # once, and a new connection may hold its handle by now (it then lost its own entry and got a 101 that was
        # not its own; its slot was taken again by its data and never freed: a slot gone for good)
        mine = self.handle is not None and self.lun.conns.get(self.handle) is self.transport
        net = self.lun.rt.devices
        if net is not None and mine:
            tr = self.transport
            net.server_transports.discard(tr)
            net._written.pop(tr, None)
            net._delayed.pop(tr, None)
        if mine:
            del self.lun.conns[self.handle]
            self.lun.paused.discard(self.handle)
            if exc is not None:
                self.lun.drop_input(self.handle)
            self.lun.push(101, self.handle)


def _lun_of(T: Any, lun: Any) -> TcpLun | None:
    dev = T.luns.get(int(lun)) if lun is not None else None
    return dev if isinstance(dev, TcpLun) else None


def _is_disk(dev: Any) -> bool:
    return type(dev) is DiskLun


def _disk_of(T: Any, lun: Any) -> Any:
    """The disk LUN ``lun`` of task ``T`` (aioadept.vplus.disk), or None."""
    # the READ/WRITE of every TCP line asks first: one dict look-up and a type test, no import
    dev = T.luns.get(int(lun)) if lun is not None else None
    return dev if type(dev) is DiskLun else None


def attach(rt: Any):
    def io_attach(T: Any, refs: tuple, text: tuple) -> Generator:
        if not refs or refs[0] is None:
            if rt.robot is None:
                raise VPlusError(E.ROBOT_NOT_ATTACHED, "*Robot not attached* (the emulator has no robot)")
            rt.robot.attach(T.num)
            T.robot_attached = True
            return
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
        if name == "DISK":
            T.luns[lun] = DiskLun(rt, T, lun)     # files in the emulator's disk folder (aioadept.vplus.disk)
            T.iostat[lun] = 1
            return
        if name != "TCP":
            T.iostat[lun] = E.NOT_ATTACHED
            rt.console(T.num, f"*Device not available* {name!r} (the emulator has TCP and DISK only)")
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
                dev.buffer_size = max(int(float(opts.get("BUFFER_SIZE") or _DEFAULT_BUFFER)), _READ_MAX)
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
            what = f"/LOCAL_PORT {vport} on {net.host}:{port}" if "LOCAL_PORT" in opts else f"{host}:{port}"
            rt.console(T.num, f"*Device error* FOPEN {what}: {exc}")
            if "LOCAL_PORT" in opts and net.on_bind_error is not None and isinstance(exc, OSError):
                net.on_bind_error(vport, net.host, port, exc)
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
        disk = _disk_of(T, lun)
        if disk is not None:
            T.iostat[lun] = disk.close()
            return
        dev = _lun_of(T, lun)
        if dev is None:
            T.iostat[lun] = E.NOT_ATTACHED
            return
        if len(refs) > 1 and refs[1] is not None:
            # FCLOSE (lun, handle): one client of a server (UNCONFIRMED form; module docstring)
            T.iostat[lun] = 1 if dev.close_handle(int(refs[1][1])) else E.DEVICE_ERROR
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
        if isinstance(dev, TcpLun) or _is_disk(dev):
            dev.close()
        T.iostat[lun] = 1
        return
        yield  # pragma: no cover

    return io_detach


def read(rt: Any):
    def io_read(T: Any, lun: Any, handle: tuple | None, mode: float, targets: tuple) -> Generator:
        n = int(lun)
        dev = T.luns.get(n)              # one look-up: a server READs several times per command
        if type(dev) is not TcpLun:
            if type(dev) is DiskLun:
                from aioadept.vplus import disk as D

                D.read(T, dev, targets)
                return
            if not isinstance(dev, TcpLun):
                T.iostat[n] = E.NOT_ATTACHED
                return
        if dev.sent:
            dev.sent.clear()
        while True:
            ev = dev.pop()
            if ev is not None:
                break
            net = rt.devices
            if net is not None and net.pending:
                # the program has read all there was: what it wrote leaves now, not when the round ends (a
                # burst of lines still gets one send for its acks; a lone ack does not wait for the rest of
                # the round: the tail of the reader's loop and the other tasks' turns)
                net.flush()
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


def getc(rt: Any):
    """GETC(lun, mode): the next byte of a TCP or disk LUN's input, without waiting for a whole record (V+
    Language User's Guide v17, p. 212: "returns the next data byte from an I/O device without waiting for a
    complete data record"). A negative value is the error instead of a byte, and is IOSTAT(lun) too: END_OF_FILE
    at the end of a disk file or of a connection, NO_DATA when ``mode`` is not 0 and nothing has arrived (mode 0,
    or omitted, waits). UNCONFIRMED: the Reference Guide's GETC page (its mode bits and codes) was not in our copy;
    these are the emulator's READ rules (docs/vplus.md). The compiled code calls it with ``yield from``."""

    def getc_(T: Any, lun: Any, mode: Any = None) -> Generator:
        n = int(lun)
        disk = _disk_of(T, n)
        if disk is not None:
            code = _disk_byte(disk)
            T.iostat[n] = 1 if code >= 0 else code
            return float(code)
        dev = _lun_of(T, n)
        if dev is None:
            T.iostat[n] = E.NOT_ATTACHED
            return float(E.NOT_ATTACHED)
        while (code := dev.byte()) is None:
            net = rt.devices
            if net is not None and net.pending:
                net.flush()          # as READ: what the program wrote leaves before it waits for the answer
            if mode:
                T.iostat[n] = E.NO_DATA
                return float(E.NO_DATA)
            T.io_wait = True
            yield rt.next_tick()
        T.iostat[n] = 1 if code >= 0 else code
        return float(code)

    return getc_


def _disk_byte(disk: Any) -> int:
    """The next byte of the file open for reading on a disk LUN (what a READ left of a long record first)."""
    if disk.file is None or disk.mode != "R":
        return E.NOT_OPEN
    if disk.rest:
        ch, disk.rest = disk.rest[0], disk.rest[1:]
        return ord(ch)
    b = disk.file.read(1)
    return b[0] if b else E.END_OF_FILE


def fcmnd(rt: Any):
    """FCMND (lun, command) ...: a device-specific command. UNCONFIRMED: the Reference Guide's FCMND page and its
    command codes were not in our copy, so no code is emulated: each sets IOSTAT(lun) to *Device error* and says
    so on the console (an I/O instruction's error never stops the program, User's Guide p. 210), rather than
    doing what we would have to guess."""

    def io_fcmnd(T: Any, refs: tuple, text: tuple) -> Generator:
        lun = _lun_number(refs)
        code = refs[1][1] if len(refs) > 1 and refs[1] is not None else None
        T.iostat[lun] = E.NOT_ATTACHED if lun not in T.luns else E.DEVICE_ERROR
        rt.console(T.num, f"*Device error* FCMND ({lun}, {code if code is None else f'{float(code):g}'}) is not "
                          "implemented by the emulator (docs/vplus.md)")
        return
        yield  # pragma: no cover

    return io_fcmnd


_FMT_N = ("fmt", "N")


def _no_wait(items: tuple) -> bool:
    for it in items:
        if type(it) is tuple and len(it) == 2 and it[0] == "fmt" and str(it[1])[:1].upper() == "N":
            return True
    return False


def write(rt: Any):
    def io_write(T: Any, lun: Any, handle: Any, items: tuple) -> Generator:
        n = int(lun)
        dev = T.luns.get(n)
        if type(dev) is not TcpLun:
            if type(dev) is DiskLun:
                _write_disk(T, dev, items)
                return
            if not isinstance(dev, TcpLun):
                T.iostat[n] = E.NOT_ATTACHED
                return
        net = rt.devices
        # A no-wait output still under way on this LUN is waited for first; if it failed, this one is cancelled
        # and IOSTAT reports the first's error (V+ Language User's Guide, "Output Wait Modes").
        if dev.nowait is not None and (st := dev.nowait_state()) != 1:
            st = yield from _wait_nowait(rt, T, dev, net, st)
            if st < 0:
                dev.nowait_err = 0
                T.iostat[n] = st
                return
        dev.nowait_err = 0
        no_wait = items[-1] == _FMT_N if items else False
        if no_wait:
            items = items[:-1]       # WRITE ..., /N of strings: _render joins them at once
        text, no_eol = _render(items)
        if not no_eol:
            text += "\r\n"
        h = int(handle) if handle is not None else (next(iter(dev.conns), -1))
        tr = dev.conns.get(h)
        if tr is None or tr.is_closing():
            T.iostat[n] = E.DEVICE_ERROR
            return
        if net is not None:
            data = text.encode("latin-1")
            if tr not in dev.sent and tr not in net.pending and not dev.events and not dev.held:
                # the first record to this connection since the LUN's last READ, and no input waits to be
                # read: it leaves now rather than after the rest of the reader's loop (a lone line's ack: the
                # here round trip); what follows it until the next READ (the acks of the other lines that READ
                # brought) waits for the flush and leaves in one send, as before
                dev.sent.add(tr)
                net._send(tr, [data])
            else:
                net.pending.setdefault(tr, []).append(data)
                net.pending_bytes[tr] = net.pending_bytes.get(tr, 0) + len(data)
        else:
            tr.write(text.encode("latin-1"))
        T.iostat[n] = 1
        if no_wait or _no_wait(items):
            dev.nowait = tr
            return
        # V+ WRITE waits until the record is out: here while the peer does not read.
        if dev.backed_up(tr) and not (yield from _wait_read(rt, T, dev, net, tr, h)):
            T.iostat[n] = E.DEVICE_ERROR

    return io_write


def _write_disk(T: Any, disk: Any, items: tuple) -> None:
    """WRITE to a disk LUN: the record, with its line end unless an item is /S."""
    from aioadept.vplus import disk as D

    text, no_eol = _render(items)
    D.write(T, disk, text if no_eol else text + "\r\n")


def _wait_nowait(rt: Any, T: Any, dev: Any, net: Any, st: int) -> Generator:
    """Wait for the no-wait output under way on ``dev`` (its state ``st`` is not 1, complete): return its final
    state (1, or its error < 0). (Its state counts what this burst has not sent yet: sent only when it is not
    complete, so that a burst of acks still leaves in one send.)"""
    if st == 0:
        if net is not None:
            net.flush()
        while (st := dev.nowait_state()) == 0:
            T.io_wait = True
            yield rt.next_tick()
    return st


def _wait_read(rt: Any, T: Any, dev: Any, net: Any, tr: Any, h: int) -> Generator:
    """Wait while more of what was written to ``tr`` (connection ``h``) is unread than the output buffer holds: return True,
    or False when the connection is lost meanwhile (reset, closed): a WRITE never waits for ever on a dead peer."""
    if net is not None:
        net.flush()
    while dev.backed_up(tr):
        if tr.is_closing() or dev.conns.get(h) is not tr:
            return False
        T.io_wait = True
        yield rt.next_tick()
    return True


def close_all(rt: Any) -> None:
    """Every TCP connection and server of every task, closed: the program has died (aioadept.vplus.cli), so no
    client may wait on for an ack that cannot come. What WRITE queued is sent first, and each connection ends
    after it (not with a reset, which may cost the client acks that had already arrived)."""
    for T in list(rt.tasks.values()):
        for dev in list(T.luns.values()):
            if isinstance(dev, TcpLun):
                dev.close(graceful=True)
    net = rt.devices
    if net is not None:
        for tr in list(net.server_transports):
            tr.close()


def release_task(rt: Any, T: Any) -> None:
    for dev in list(T.luns.values()):
        if isinstance(dev, TcpLun) or _is_disk(dev):
            dev.close()
    T.luns.clear()
