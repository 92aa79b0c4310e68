"""Crowds of peers on a server's stop port, and a newcomer's stop through them (docs/protocol.md 4.2.1).

For the tests (tests/conformance/test_server_stop_port_crowds.py) and benchmarks/bench_safety.py, which run a crowd
as a real process: ``python -m aioadept.testing.crowds KIND HOST PORT N`` prints ``READY`` once its peers are
started and runs until killed. Kinds:

- ``monitors``: N well-behaved monitors, each on a connection of its own sending ``here`` every 0.5 s and reading
  the acks; one whose connection is closed connects again at its next poll.
- ``storm``: N loops of short-lived connections, one after the other: connect, send ``here``, read its ack, stay
  0.5 s (less than the stop port's idle time), close.
- ``slowloris``: N peers that each trickle a line that never ends (one byte every 0.1 s); one whose connection is
  closed (or refused) connects again at once.

:func:`stop_through` is the newcomer: it connects to the stop port and sends ``stop`` until one is acked ``done``,
as an operator's emergency-stop tool would, and returns how long that took.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import sys

KINDS = ("monitors", "storm", "slowloris")
_ids = itertools.count(0x20000000)


def _mid() -> bytes:
    return b"%08x" % (next(_ids) % 0x7FFFFFFF or 1)


async def _close(writer: asyncio.StreamWriter) -> None:
    writer.close()
    with contextlib.suppress(OSError):
        await writer.wait_closed()


async def monitor(host: str, port: int, period_s: float = 0.5) -> None:
    while True:
        try:
            reader, writer = await asyncio.open_connection(host, port)
        except OSError:
            await asyncio.sleep(period_s)
            continue
        try:
            while True:
                writer.write(_mid() + b":here\r\n")
                await writer.drain()
                async with asyncio.timeout(5):
                    if not await reader.readuntil(b"\r\n"):
                        break
                await asyncio.sleep(period_s)
        except (OSError, asyncio.IncompleteReadError, TimeoutError):
            pass
        finally:
            await _close(writer)
        await asyncio.sleep(period_s)  # connects again at its next poll


async def storm(host: str, port: int, hold_s: float = 0.5) -> None:
    while True:
        try:
            reader, writer = await asyncio.open_connection(host, port)
        except OSError:
            await asyncio.sleep(0.001)
            continue
        try:
            writer.write(_mid() + b":here\r\n")
            async with asyncio.timeout(1):
                await reader.readuntil(b"\r\n")
            await asyncio.sleep(hold_s)
        except (OSError, asyncio.IncompleteReadError, TimeoutError):
            pass
        finally:
            writer.transport.abort()


async def slowloris(host: str, port: int) -> None:
    while True:
        try:
            reader, writer = await asyncio.open_connection(host, port)
        except OSError:
            await asyncio.sleep(0.001)
            continue
        try:
            writer.write(b"deadbeef:")
            while not reader.at_eof() and not writer.is_closing():
                writer.write(b"h")
                await writer.drain()
                await asyncio.sleep(0.1)
        except OSError:
            pass
        finally:
            writer.transport.abort()


async def crowd(kind: str, host: str, port: int, n: int) -> None:
    peer = {"monitors": monitor, "storm": storm, "slowloris": slowloris}[kind]
    tasks = [asyncio.create_task(peer(host, port)) for _ in range(n)]
    await asyncio.sleep(0.5)  # the peers have connected
    print("READY", kind, n, flush=True)
    await asyncio.gather(*tasks)


async def stop_through(host: str, port: int, *, within_s: float = 10.0, wait_ack_s: float = 2.0) -> float:
    """Send ``stop`` on a fresh connection to ``port`` until one is acked ``done``; the seconds that took. A
    connection that is refused or closed before the ack is tried again at once (a tool's retry). Raises
    TimeoutError after ``within_s``."""
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    async with asyncio.timeout(within_s):
        while True:
            mid = _mid()
            try:
                reader, writer = await asyncio.open_connection(host, port)
            except OSError:
                await asyncio.sleep(0.005)
                continue
            try:
                writer.write(mid + b":stop\r\n")
                async with asyncio.timeout(wait_ack_s):
                    while True:
                        line = await reader.readuntil(b"\r\n")
                        if line.startswith(mid + b":done:"):
                            return loop.time() - t0
            except (OSError, asyncio.IncompleteReadError, TimeoutError):
                await asyncio.sleep(0.005)
            finally:
                writer.transport.abort()


def main(argv: list[str]) -> int:
    if len(argv) != 4 or argv[0] not in KINDS:
        print(f"usage: python -m aioadept.testing.crowds {{{','.join(KINDS)}}} HOST PORT N", file=sys.stderr)
        return 2
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(crowd(argv[0], argv[1], int(argv[2]), int(argv[3])))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
