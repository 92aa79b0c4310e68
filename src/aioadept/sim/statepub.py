"""The simulated controller's state stream: ``robot.state`` (and ``world.state``) at a fixed rate, one sample more
when a motion ends, and after the server's death the braked arm coming to rest.

It observes the arm, it never drives it: a sample that cannot be *sent* (a full or closed socket) is dropped and
the stream goes on, logged once per run of such failures; a sample that cannot be *computed* is the robot model's
bug, the one the executor runs on, and is reported to the owner (:class:`~aioadept.sim.server.SimServer` dies of
it). The samples and the publisher are given to it, so it runs without a server or a socket in tests.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from typing import Any

__all__ = ["SAMPLE_FAILED", "MOTION_END_SAMPLE_FAILED", "STREAM_FAILED", "SendFailures", "StatePublisher",
           "next_period"]

log = logging.getLogger(__name__)

SAMPLE_FAILED = "sample"
"""``failed(SAMPLE_FAILED, exc)``: a periodic sample could not be computed (the stream has ended)."""
MOTION_END_SAMPLE_FAILED = "motion-end"
"""``failed(MOTION_END_SAMPLE_FAILED, exc)``: the sample at a motion's end could not be computed."""
STREAM_FAILED = "stream"
"""``failed(STREAM_FAILED, exc)``: the stream's task died outside the per-sample guards (its own bug)."""


class SendFailures:
    """The state stream's failures to send, logged once per run of them (not one traceback per sample, 100 a
    second): the first failure says what failed, the first success after it how many samples were dropped."""

    __slots__ = ("dropped", "first")

    def __init__(self) -> None:
        self.dropped = 0
        self.first: str | None = None

    def send(self, send: Callable[[], None]) -> None:
        try:
            send()
        except Exception as exc:  # noqa: BLE001 - a full or closed socket, a transport error: drop the sample
            if not self.dropped:
                self.first = f"{type(exc).__name__}: {exc}"
                log.warning("state stream: a sample was not sent (%s); dropping samples until one is",
                            self.first)
            self.dropped += 1
            return
        if self.dropped:
            log.warning("state stream: sending again after %d dropped samples (%s)", self.dropped, self.first)
            self.dropped, self.first = 0, None


async def next_period(loop: asyncio.AbstractEventLoop, next_t: float, period: float) -> float:
    """Sleep until ``next_t + period`` and return that time: a fixed schedule, not sleep(period) after the
    work, so the rate does not drift; a schedule fallen behind (suspended, overloaded) skips the missed samples."""
    next_t += period
    delay = next_t - loop.time()
    if delay < -period:
        next_t = loop.time()
        delay = 0.0
    await asyncio.sleep(max(delay, 0.0))
    return next_t


class StatePublisher:
    """Publishes ``sample()`` (a ``(RobotState, WorldState | None)`` pair) on ``publisher`` at ``rate_hz``.

    ``failed(kind, exc)`` is told when a sample cannot be computed or the stream's task dies (``kind``: one of
    :data:`SAMPLE_FAILED`, :data:`MOTION_END_SAMPLE_FAILED`, :data:`STREAM_FAILED`). ``send_fault``: every sample
    of a moving arm fails to send (``Faults(raise_at="state-send")``, tests of a broken stream).
    """

    def __init__(self, publisher: Any, sample: Callable[[], tuple[Any, Any]], rate_hz: float, *,
                 failed: Callable[[str, BaseException], None], send_fault: bool = False) -> None:
        self.publisher = publisher
        self.sample = sample
        self.period = 1.0 / rate_hz
        self.failed = failed
        self.send_fault = send_fault
        self.failures = SendFailures()
        self.halted = False
        self._task: asyncio.Task[None] | None = None

    def start(self) -> None:
        self._task = asyncio.get_running_loop().create_task(self.run(), name="sim-state")
        self._task.add_done_callback(self._task_ended)

    def halt(self) -> None:
        """Publish no more periodic samples (the owner is dying; :meth:`show_rest` still may)."""
        self.halted = True

    async def stop(self) -> None:
        """End the periodic samples and wait until their task has ended."""
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)

    def send(self, robot: Any, world: Any) -> None:
        """Publish one sample now (raises what the publisher raises)."""
        from aioadept.bus.messages import ROBOT_STATE_TOPIC, WORLD_STATE_TOPIC
        from aioadept.errors import BusError

        # Decided on the sample itself, not on the clock at sending: a sample taken in the last moment of a motion
        # and sent just after it ended is a sample of the moving arm.
        if self.send_fault and robot.in_motion:
            raise BusError("injected state-send fault")
        self.publisher.publish_nowait(ROBOT_STATE_TOPIC, robot.to_bytes())
        if world is not None:
            self.publisher.publish_nowait(WORLD_STATE_TOPIC, world.to_bytes())

    def publish_now(self) -> None:
        """One sample now, out of schedule (a motion has ended: subscribers see the arm at rest before any request
        that follows the ack, not up to one period later)."""
        try:
            robot, world = self.sample()
        except Exception as exc:  # noqa: BLE001 - the robot model, not the stream, is broken
            self.failed(MOTION_END_SAMPLE_FAILED, exc)
            return
        self.failures.send(lambda: self.send(robot, world))

    async def run(self) -> None:
        """The periodic samples, until halted or cancelled, or until a sample cannot be computed."""
        loop = asyncio.get_running_loop()
        next_t = loop.time()
        while not self.halted:
            try:
                robot, world = self.sample()
            except Exception as exc:  # noqa: BLE001
                self.failed(SAMPLE_FAILED, exc)
                return
            self.failures.send(lambda r=robot, w=world: self.send(r, w))
            next_t = await next_period(loop, next_t, self.period)

    async def show_rest(self, in_motion: Callable[[], bool], wait_s: float) -> None:
        """After the owner's death: publish until ``in_motion()`` is false (at most ``wait_s``) and two samples
        more, so a subscriber's last sample shows the arm at rest. The periodic task may be what died, so this
        publishes on its own; a sample that fails is skipped quietly (the owner has said what died)."""
        await self.stop()
        loop = asyncio.get_running_loop()
        t_end = loop.time() + wait_s
        extra = 2
        while extra > 0 and loop.time() < t_end:
            try:
                moving = in_motion()
            except Exception:  # noqa: BLE001
                moving = False
            if not moving:
                extra -= 1
            with contextlib.suppress(Exception):
                self.send(*self.sample())
            await asyncio.sleep(self.period)

    def _task_ended(self, task: asyncio.Task[None]) -> None:
        # A failure outside the per-sample guards (a bug of the loop itself) would end the stream silently: the
        # subscribers would see a server whose arm no longer reports, while it still moves it.
        if not task.cancelled() and task.exception() is not None:
            self.failed(STREAM_FAILED, task.exception())  # type: ignore[arg-type]
