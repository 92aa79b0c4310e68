"""The state stream of a V+ controller, relayed onto the bus: TCP lines in, ``robot.state`` messages out.

The V+ server's state task (``vplus/rsstate.V2``) writes one text line per sample on a TCP port of its own
(docs/protocol.md, section 9). :class:`StateRelay` holds one connection to that port, parses each line with the
sans-IO :func:`aioadept.protocol.statestream.parse_state_line` and publishes it as the same
:class:`aioadept.bus.messages.RobotState` the simulator publishes, so the live view, the recording and the virtual
camera work the same on a real controller. ``aioadept state`` (:mod:`aioadept.cli.state`) runs it as a node.

The controller's clock (``t``, seconds since the server started) becomes wall time with the smallest offset seen
on the connection (``receive time - t``): the sample that arrived fastest bounds the transport delay, so
``wall_time_s`` is never later than the sample really was, and stays monotonic in ``t``. A lost connection is
retried with backoff (0.1 s doubling to ``max_backoff_s``) for as long as the relay runs, and so is one that brings
nothing for ``idle_timeout_s``; a reconnect starts a new offset (the server may have restarted, and its clock
with it).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from dataclasses import dataclass
from typing import Any

from aioadept.errors import RemoteProtocolError
from aioadept.protocol.framing import LineFramer, Oversize
from aioadept.protocol.statestream import MAX_STATE_LINE, StateSample, parse_state_line

log = logging.getLogger(__name__)

RETRY_NOTICE_S = 10.0
"""While the state port cannot be reached, a WARNING at the first failure and then at most this often."""


def to_robot_state(sample: StateSample, wall_time_s: float):  # -> aioadept.bus.messages.RobotState
    """The bus message for one state line (``speed_pct`` rounded to an integer, as the sim publishes it)."""
    from aioadept.bus.messages import RobotState

    return RobotState(t_s=sample.t_s, wall_time_s=wall_time_s, joints_deg=sample.joints_deg, pose=sample.pose,
                      in_motion=sample.moving, speed_pct=int(round(sample.speed_pct)), air=sample.air)


@dataclass
class RelayStats:
    """Counters of a :class:`StateRelay`, for tests and the log."""

    connections: int = 0
    lines: int = 0
    published: int = 0
    skipped: int = 0
    """Lines of another format tag, malformed lines and oversize lines (each logged once per connection)."""


class StateRelay:
    """Connect to ``host:port`` (the V+ state port) and publish every sample on ``robot.state`` with ``publisher``
    (an :class:`aioadept.bus.pubsub.Publisher`, owned by the caller). ``await relay.run()`` until cancelled."""

    def __init__(self, host: str, port: int, publisher: Any, *, connect_timeout_s: float = 5.0,
                 max_backoff_s: float = 2.0, idle_timeout_s: float = 2.0) -> None:
        if not (connect_timeout_s > 0 and max_backoff_s > 0 and idle_timeout_s > 0):
            raise ValueError("connect_timeout_s, max_backoff_s and idle_timeout_s must be > 0")
        self.idle_timeout_s = idle_timeout_s
        """A connection that brings no data for this long is closed and made again (a controller that hung or a
        cable pulled: TCP alone may not notice for minutes). The shipped task writes 100 lines a second."""
        self.host = host
        self.port = port
        self.publisher = publisher
        self.connect_timeout_s = connect_timeout_s
        self.max_backoff_s = max_backoff_s
        self.stats = RelayStats()
        self.connected = asyncio.Event()
        self.last: StateSample | None = None

    async def run(self) -> None:
        """Relay until cancelled, reconnecting with backoff whenever the connection is lost or refused."""
        backoff = 0.1
        failures, told = 0, -math.inf
        while True:
            try:
                async with asyncio.timeout(self.connect_timeout_s):
                    reader, writer = await asyncio.open_connection(self.host, self.port)
            except (OSError, TimeoutError) as exc:
                failures += 1
                now = time.monotonic()
                # Visible at once and then every RETRY_NOTICE_S, so a wrong address is never silence.
                level = logging.WARNING if now - told >= RETRY_NOTICE_S else logging.DEBUG
                told = now if level == logging.WARNING else told
                log.log(level, "no state stream at %s:%d (%s); still trying (%d attempt%s)", self.host, self.port,
                        self._why(exc), failures, "" if failures == 1 else "s")
                await asyncio.sleep(backoff)
                backoff = min(backoff * 2, self.max_backoff_s)
                continue
            if failures:
                log.warning("state stream %s:%d connected after %d failed attempts", self.host, self.port, failures)
            backoff, failures, told = 0.1, 0, -math.inf
            self.stats.connections += 1
            self.connected.set()
            try:
                await self._relay(reader)
            finally:
                self.connected.clear()
                writer.close()
                with contextlib.suppress(OSError):
                    await writer.wait_closed()
            log.warning("state stream %s:%d closed; reconnecting", self.host, self.port)

    def _why(self, exc: BaseException) -> str:
        if isinstance(exc, ConnectionRefusedError):
            return "nothing listens there"
        if isinstance(exc, TimeoutError):
            return f"no answer in {self.connect_timeout_s:g} s"
        return getattr(exc, "strerror", None) or str(exc) or type(exc).__name__

    async def _relay(self, reader: asyncio.StreamReader) -> None:
        from aioadept.bus.messages import ROBOT_STATE_TOPIC

        framer = LineFramer(max_line=MAX_STATE_LINE)
        offset: float | None = None
        complained = False
        while True:
            try:
                async with asyncio.timeout(self.idle_timeout_s):
                    chunk = await reader.read(65536)
            except TimeoutError:
                log.warning("state stream %s:%d: no data for %g s", self.host, self.port, self.idle_timeout_s)
                return
            except OSError:
                return
            if not chunk:
                return
            now = time.time()
            for item in framer.feed(chunk):
                self.stats.lines += 1
                try:
                    if isinstance(item, Oversize):
                        raise RemoteProtocolError(0, f"line longer than {MAX_STATE_LINE} bytes")
                    sample = parse_state_line(item)
                except RemoteProtocolError as exc:
                    sample = None
                    if not complained:
                        log.warning("state stream: %s", exc.message)
                        complained = True
                if sample is None:
                    self.stats.skipped += 1
                    continue
                off = now - sample.t_s
                if offset is None or off < offset:
                    offset = off
                self.last = sample
                try:
                    msg = to_robot_state(sample, offset + sample.t_s)
                    self.publisher.publish_nowait(ROBOT_STATE_TOPIC, msg.to_bytes())
                    self.stats.published += 1
                except Exception:
                    log.exception("state publish failed")


__all__ = ["RelayStats", "StateRelay", "to_robot_state"]
