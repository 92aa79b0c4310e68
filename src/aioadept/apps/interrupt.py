"""Ctrl-C (and a closed terminal) in the command-line apps (``aioadept focus``, ``demo``, ``experiment``, ``send``): stop
the robot first.

A robot cell's operator presses Ctrl-C to make the arm stop, not to make the program tidy up while the arm goes on.
So an :class:`Interrupter` replaces asyncio's default SIGINT behaviour (cancel the main task, whose cleanup may
well start a motion) with:

- **first SIGINT (or SIGTERM, or SIGHUP):** in the signal callback itself, write ``stop`` on every attached robot connection
  (``RobotClient.stop_nowait``: written in that call, before any other task of this process runs again), then cancel the
  app's main task. The app's cleanup starts no motion (see :func:`aioadept.apps.paper.ufloop`); a robot connection
  that is closing first waits for the stop's ack (:meth:`Interrupter.guard`), so the stop is confirmed, not hoped.
  SIGHUP is the terminal or SSH session that ran the app going away: by default it kills the process mid-motion,
  with no stop sent and the arm running to the end of its move, so it gets the same policy.
  Messages to a terminal that is gone are dropped (:func:`_say`); the exit code still tells.
- **second signal:** exit at once: ``stop`` is written again where a connection is open, every child node process
  (:mod:`aioadept.apps.processes`) is killed, and the process ends with code 130 and one line on stderr.

:func:`run_interruptible` runs an app's coroutine under it and turns the outcome into the exit code: 130 when the
interrupt's stop was acked (or nothing was connected), 1 with a one-line message when a stop failed.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import sys
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

from aioadept.commands import Skill

EXIT_INTERRUPTED = 130
"""Exit code after an interrupt whose stop was acked (128 + SIGINT, as shells report it)."""
EXIT_STOP_FAILED = 1
"""Exit code after an interrupt whose stop could not be confirmed: the robot may still be moving."""


STOP_SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""The signals that stop the robot and end an app that moves it: Ctrl-C, ``kill``, and the terminal closing."""


class Interrupter:
    """The stop-signal policy (:data:`STOP_SIGNALS`) of one app run. See the module docstring.

    ``stop_timeout_s``: how long a stop's ack is awaited (the server acks it when the arm is at rest).
    """

    def __init__(self, prog: str, *, stop_timeout_s: float = 10.0, stop_failed_code: int = EXIT_STOP_FAILED) -> None:
        self.prog = prog
        self.stop_failed_code = stop_failed_code
        self.stop_timeout_s = stop_timeout_s
        self.count = 0
        """Signals received so far."""
        self.signal_name = ""
        self._robots: list[Any] = []
        self._stops: list[tuple[Any, asyncio.Future[Any]]] = []
        self._task: asyncio.Task[Any] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self.t_signal_s: float | None = None
        """Loop time of the first signal."""

    # -- installing
    def install(self, task: asyncio.Task[Any] | None = None) -> None:
        """Handle :data:`STOP_SIGNALS` in the running loop; the first one cancels ``task`` (default: the current one).

        The handlers stay until the loop closes, so a second Ctrl-C during the app's cleanup still exits at once.
        """
        self._loop = asyncio.get_running_loop()
        self._task = task or asyncio.current_task()
        for sig in STOP_SIGNALS:
            self._loop.add_signal_handler(sig, self._on_signal, sig)

    @property
    def interrupted(self) -> bool:
        return self.count > 0

    # -- robots
    @contextlib.asynccontextmanager
    async def guard(self, robot: Any) -> AsyncIterator[Any]:
        """Attach a connected :class:`~aioadept.client.RobotClient` for the duration of the block.

        An interrupt inside the block writes ``stop`` on it; on leaving the block after an interrupt, the stop's
        ack is awaited (bounded by ``stop_timeout_s``) before the caller closes the connection, so closing never
        turns a stop in flight into a lost one.
        """
        self._robots.append(robot)
        if self.count:  # attached after the interrupt: stop it too
            self._send_stop(robot)
        try:
            yield robot
        finally:
            try:
                if self.count:
                    await self.settle()
            finally:
                self._robots.remove(robot)

    def _on_signal(self, signum: int) -> None:
        self.count += 1
        if self.count > 1:
            self._exit_now()
            return
        assert self._loop is not None
        self.t_signal_s = self._loop.time()
        self.signal_name = signal.Signals(signum).name
        # The stop goes out before anything else: it is written here, in the signal callback.
        for robot in list(self._robots):
            self._send_stop(robot)
        if self._task is not None and not self._task.done():
            self._task.cancel()
        _say(f"{self.prog}: {self.signal_name}: stopping the robot (press Ctrl-C again to exit at once)")

    def _send_stop(self, robot: Any) -> None:
        # stop_nowait writes the stop in this call when connected (before any other task runs), makes calls still
        # waiting to write raise instead of writing after it, and otherwise reconnects (auto_reconnect) or fails
        # with a typed error: the outcome is reported either way, never taken for success.
        try:
            fut: asyncio.Future[Any] = robot.stop_nowait(timeout_s=self.stop_timeout_s)
        except Exception as exc:  # e.g. no running loop or a closed client: report it as a failed stop
            fut = asyncio.get_running_loop().create_future()
            fut.set_exception(exc)
        self._stops.append((robot, fut))

    async def settle(self) -> list[tuple[Any, Any]]:
        """Wait for every stop sent so far; returns ``(robot, MessageResult or exception)`` per stop."""
        futs = [f for _, f in self._stops]
        if futs:
            await asyncio.wait(futs, timeout=self.stop_timeout_s + 1.0)
        out: list[tuple[Any, Any]] = []
        for robot, fut in self._stops:
            if not fut.done():
                fut.cancel()
                out.append((robot, TimeoutError(f"no ack to the stop within {self.stop_timeout_s} s")))
            elif fut.cancelled():
                out.append((robot, TimeoutError("the wait for the stop's ack was cancelled")))
            elif fut.exception() is not None:
                out.append((robot, fut.exception()))
            else:
                out.append((robot, fut.result()))
        return out

    async def report(self) -> int:
        """After an interrupt: one line on stderr saying whether the robot was stopped; returns the exit code."""
        outcomes = await self.settle()
        failed = [(r, o) for r, o in outcomes if isinstance(o, BaseException)]
        if failed:
            robot, exc = failed[0]
            _say(f"{self.prog}: interrupted, but the stop FAILED on {robot.host}:{robot.port}: "
                 f"{type(exc).__name__}: {exc}; the robot may still be moving")
            return self.stop_failed_code
        if not outcomes:
            _say(f"{self.prog}: interrupted; no robot was connected, nothing to stop")
            return EXIT_INTERRUPTED
        res = outcomes[-1][1]
        p = res.ack.pose
        _say(f"{self.prog}: interrupted: robot stopped (stop acked {res.ack.status.value} after "
             f"{res.rtt_s * 1e3:.0f} ms) at x={p.x:.3f} y={p.y:.3f} z={p.z:.3f} mm")
        return EXIT_INTERRUPTED

    def _exit_now(self) -> None:
        from aioadept.apps.processes import kill_all_now

        for robot in list(self._robots):
            with contextlib.suppress(Exception):  # best effort: we are leaving anyway
                robot.submit(_STOP)
        killed = kill_all_now()
        more = f"; {killed} child node(s) killed" if killed else ""
        _say(f"{self.prog}: interrupted again: exiting now{more}")
        os._exit(EXIT_INTERRUPTED)


_STOP = Skill("stop")


def interrupt_handled() -> None:
    """Tell CPython that a KeyboardInterrupt this program caught was handled.

    CPython 3.11 raises the interrupt wherever the main thread is; when that is inside ``exec()`` of a string
    (``dataclasses`` builds its methods so, at import time) it sets the interpreter's "unhandled KeyboardInterrupt"
    flag although the program catches the exception, and at exit the process kills itself with SIGINT: exit status
    -2 instead of the 130 the app returned (2 of 40 demos interrupted during their analysis). Clearing the flag
    is a no-op where it does not exist."""
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.c_int.in_dll(ctypes.pythonapi, "_Py_UnhandledKeyboardInterrupt").value = 0


def _say(line: str) -> None:
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(line + "\n")
        sys.stderr.flush()


def run_interruptible(main: Callable[[Interrupter], Awaitable[int]], *, prog: str,
                      stop_timeout_s: float = 10.0, stop_failed_code: int = EXIT_STOP_FAILED) -> int:
    """``asyncio.run(main(interrupter))`` with the interrupt policy installed; returns the exit code.

    ``main`` attaches its robot connections with ``interrupter.guard(robot)``. After an interrupt the result is
    :meth:`Interrupter.report`'s code, whatever ``main`` did with the cancellation.
    """
    intr = Interrupter(prog, stop_timeout_s=stop_timeout_s, stop_failed_code=stop_failed_code)

    async def wrapper() -> int:
        task = asyncio.current_task()
        assert task is not None
        intr.install(task)
        try:
            code = await main(intr)
        except asyncio.CancelledError:
            if not intr.count:
                raise
            task.uncancel()
            return await intr.report()
        except BaseException:
            if intr.count:  # the cancellation surfaced as another error (e.g. a node stopped under us)
                return await intr.report()
            raise
        if intr.count:
            return await intr.report()
        return int(code)

    try:
        return asyncio.run(wrapper())
    except KeyboardInterrupt:  # a SIGINT before the handler was installed: nothing was connected yet
        interrupt_handled()
        _say(f"{prog}: interrupted")
        return EXIT_INTERRUPTED
