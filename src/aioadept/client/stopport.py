"""The client's stop on the server's stop port, and the race between it and the stop on the main connection.

The stop port (docs/protocol.md 4.2.1) is a second TCP port of the server that serves only ``stop``, ``here`` and
``hello``. :func:`stop_on_port` sends one ``stop`` there on a connection of its own and returns its result;
:func:`race_stop` awaits the stop already written on the main connection and, when no ack has come after a while,
sends it on the stop port as well: the first ``done`` wins (a second stop cannot move the robot).
:func:`open_side_socket` and :func:`drop_unsent_on_close` serve the opt-in side path (``stop_side_path``): a stop
stuck behind unsent bytes goes first on a new connection, and the old one is reset so its unsent commands never
reach the server.
"""

from __future__ import annotations

import asyncio
import logging
import secrets
import socket
import struct
from collections.abc import Awaitable, Callable

from aioadept.client.results import MessageResult, SentMessage
from aioadept.client.transport import set_nodelay
from aioadept.errors import AckTimeout, CommandAborted, CommandError, ConnectError, ConnectionLost
from aioadept.protocol import STOP_SKILL, Status, parse_ack

__all__ = ["STOP_FAILURES", "drop_unsent_on_close", "open_side_socket", "race_stop", "stop_on_port"]

log = logging.getLogger("aioadept.client")

STOP_FAILURES = (ConnectionLost, ConnectError, AckTimeout, CommandError, CommandAborted)
"""How a stop on one path fails while the other path may still deliver it."""


async def stop_on_port(host: str, port: int, timeout_s: float, *,
                       on_send: Callable[[SentMessage], None] | None = None,
                       on_ack: Callable[[MessageResult], None] | None = None) -> MessageResult:
    """Send ``stop`` to ``host:port`` on a new connection (closed after the ack) and return its result on the
    ``done`` ack. ``on_send`` / ``on_ack`` see the message and its result as a client's observers do.

    Raises :class:`ConnectError` if the port cannot be reached or closes without answering, :class:`AckTimeout`
    after ``timeout_s`` (the connect included), :class:`CommandError` / :class:`CommandAborted` for an error or
    aborted ack.
    """
    mid = f"{secrets.randbits(32) or 1:08x}"
    loop = asyncio.get_running_loop()
    t_send = loop.time()
    writer = None
    try:
        async with asyncio.timeout(timeout_s):
            reader, writer = await asyncio.open_connection(host, port)
            set_nodelay(writer)
            t_send = loop.time()
            writer.write(f"{mid}:{STOP_SKILL}\r\n".encode())
            if on_send is not None:
                on_send(SentMessage(mid, STOP_SKILL, (), 0, t_send))
            while True:
                line = await reader.readuntil(b"\n")
                try:
                    ack = parse_ack(line.rstrip(b"\r\n"))
                except Exception:  # noqa: BLE001 - not an ack of ours (a refusal line, noise): read on
                    continue
                if ack.id == mid:
                    break
    except TimeoutError:
        raise AckTimeout(f"stop on the stop port {host}:{port}: no ack within {timeout_s} s",
                         pending=(mid,)) from None
    except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError) as exc:
        raise ConnectError(f"stop port {host}:{port}: {exc or type(exc).__name__}") from exc
    finally:
        if writer is not None:
            writer.close()
    result = MessageResult(mid, STOP_SKILL, (), 0, t_send, loop.time(), ack)
    if on_ack is not None:
        on_ack(result)
    if ack.status is Status.ERROR:
        raise CommandError(ack, STOP_SKILL)
    if ack.status is not Status.DONE:
        raise CommandAborted(ack, STOP_SKILL)
    return result


async def race_stop(main: Awaitable[MessageResult], side: Callable[[], Awaitable[MessageResult]] | None,
                    after_s: float, *, peer: str) -> MessageResult:
    """Await ``main`` (the stop written on the main connection, to ``peer``); if it has not finished ``after_s``
    after this call, start ``side()`` (the stop on the stop port) too. The first result wins and the other is
    cancelled; a failure (:data:`STOP_FAILURES`) counts only when both have failed, and then ``main``'s is raised.
    ``side=None``: no stop port, ``main`` alone."""
    main_task = asyncio.ensure_future(main)
    if side is None:
        return await main_task
    done, _ = await asyncio.wait({main_task}, timeout=after_s)
    if done:
        return main_task.result()
    log.warning("stop: no ack from %s after %.2f s; sending it on the stop port too", peer, after_s)
    side_task = asyncio.ensure_future(side())
    errors: list[BaseException] = []
    try:
        for fut in asyncio.as_completed((main_task, side_task)):
            try:
                return await fut
            except STOP_FAILURES as exc:
                errors.append(exc)
    finally:
        for task in (main_task, side_task):
            if not task.done():
                task.cancel()
    main_exc = main_task.exception() if main_task.done() and not main_task.cancelled() else errors[0]
    raise main_exc if main_exc is not None else errors[0]


async def open_side_socket(host: str, port: int, timeout_s: float) -> socket.socket:
    """A new non-blocking TCP socket connected to ``host:port`` (raises OSError, or TimeoutError after
    ``timeout_s``), for the client to adopt as its connection."""
    loop = asyncio.get_running_loop()
    async with asyncio.timeout(timeout_s):
        infos = await loop.getaddrinfo(host, port, type=socket.SOCK_STREAM)
        family, type_, proto, _, addr = infos[0]
        side = socket.socket(family, type_, proto)
        try:
            side.setblocking(False)
            await loop.sock_connect(side, addr)
        except BaseException:
            side.close()
            raise
    return side


def drop_unsent_on_close(transport: asyncio.BaseTransport) -> None:
    """SO_LINGER 0 on ``transport``'s socket: closing it then sends RST and drops the kernel's unsent bytes too,
    so nothing written before reaches the peer after that."""
    sock = transport.get_extra_info("socket")
    if sock is not None:
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        except OSError:
            pass
