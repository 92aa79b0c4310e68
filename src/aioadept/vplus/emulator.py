"""The public face of the V+ emulator: load ``.V2`` files, call programs, read variables, run tasks.

For unit tests of V+ code, in virtual time (deterministic, as fast as the host runs)::

    from aioadept.vplus import Emulator

    emu = Emulator.load("vplus/rserver.V2", "vplus/rsskills.V2", "vplus/rsconfig.V2")
    emu.call("rs.init")
    r = emu.call("rs.itoa", -406, "")          # arguments: values; variables come back in r.args
    assert r.args[1] == "-406"
    assert emu.globals["rs.port"] == 1234

For the TCP server (``aioadept sim --vplus``) the same emulator runs in real time: :meth:`Emulator.serve`.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aioadept.errors import AdeptError
from aioadept.vplus.errors import VPlusError
from aioadept.vplus.loader import LoadProblem, Module, load_files, load_text
from aioadept.vplus.parse import norm
from aioadept.vplus.runtime import STORAGE_LIMIT, RealClock, Runtime, Task, VirtualClock, f32


class LoadError(AdeptError):
    """Raised by ``Emulator.load(..., strict=True)`` when a line did not load."""

    def __init__(self, problems: list[LoadProblem]) -> None:
        super().__init__("\n".join(map(str, problems)))
        self.problems = problems


@dataclass(frozen=True)
class CallResult:
    """What :meth:`Emulator.call` returns: the arguments' values after the call (by-reference results)."""

    args: tuple
    task: int
    time_s: float


class GlobalsView(Mapping):
    """The global variables by V+ name: ``x``, ``$s``, ``#p``; an array (``a`` or ``a[]``) reads as a dict."""

    def __init__(self, data: dict[str, Any]) -> None:
        self._d = data

    def _key(self, name: str) -> str:
        arr = name.endswith("[]")
        key = norm(name[:-2] if arr else name)
        if arr or (key not in self._d and key + "[]" in self._d):
            return key + "[]"
        return key

    def __getitem__(self, name: str) -> Any:
        return self._d[self._key(name)]

    def __setitem__(self, name: str, value: Any) -> None:
        key = self._key(name)
        if isinstance(value, (list, tuple)) and not key.startswith("#"):
            value = dict(enumerate(_to_vplus(v) for v in value))
            key = key if key.endswith("[]") else key + "[]"
        elif isinstance(value, dict):
            value = {k: _to_vplus(v) for k, v in value.items()}
            key = key if key.endswith("[]") else key + "[]"
        else:
            value = _to_vplus(value)
        self._d[key] = value

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and self._key(name) in self._d

    def __iter__(self):
        return iter(self._d)

    def __len__(self) -> int:
        return len(self._d)


def _to_vplus(v: Any) -> Any:
    if isinstance(v, bool):
        return -1.0 if v else 0.0
    if isinstance(v, (int, float)):
        return f32(float(v))
    return v


class Emulator:
    """A loaded set of V+ modules with its global data, tasks and (by default) the simulated Viper."""

    def __init__(self, module: Module, *, robot: Any = True, clock: Any = None, cycle_s: float = 0.016,
                 console: Callable[[int, str], None] | None = None, disk_dir: str | Path | None = None,
                 storage_limit: int = STORAGE_LIMIT) -> None:
        """``storage_limit``: array elements all programs may hold (runtime.STORAGE_LIMIT, docs/vplus.md)."""
        from aioadept.vplus.disk import DiskFolder

        self.clock = clock or VirtualClock()
        if robot is True:
            robot = make_robot()
        self.rt = Runtime(module, clock=self.clock, cycle_s=cycle_s, console=console, robot=robot or None,
                          storage_limit=storage_limit)
        # disk files (FOPENR ...) live in this folder only; None: a new temporary folder (aioadept.vplus.disk)
        self.rt.disk = DiskFolder(disk_dir)
        ctl = getattr(self.rt.robot, "controller", None)
        if ctl is not None:
            # SIGNAL, SIG(), BITS and the hand act on the sim's I/O model: SIGNAL 8 is its air valve, CLOSEI its
            # gripper, and its state stream sees every change
            self.rt.io = ctl.io
            self.rt.signals = ctl.io.values

    # -- construction ---------------------------------------------------------------------------------------
    @classmethod
    def load(cls, *paths: str | Path, strict: bool = False, **options: Any) -> Emulator:
        """Load ``.V2`` files. Lines that do not load are in :attr:`problems` (``strict``: raise instead)."""
        module = load_files(list(paths))
        emu = cls(module, **options)
        if strict and emu.problems:
            raise LoadError(emu.problems)
        return emu

    @classmethod
    def from_source(cls, text: str, *, filename: str = "<source>", strict: bool = False, **options: Any) -> Emulator:
        """Load V+ source text (one or more ``.PROGRAM`` sections)."""
        module = load_text(text, filename, Module())
        emu = cls(module, **options)
        if strict and emu.problems:
            raise LoadError(emu.problems)
        return emu

    # -- inspection ---------------------------------------------------------------------------------------
    @property
    def problems(self) -> list[LoadProblem]:
        return self.rt.problems

    @property
    def globals(self) -> GlobalsView:
        return GlobalsView(self.rt.globals)

    @property
    def console(self) -> list[str]:
        """Console lines so far: TYPE output and task messages, ``"[task] text"``."""
        return [f"[{t}] {s}" for t, s in self.rt.console_lines]

    @property
    def time_s(self) -> float:
        return self.rt.now

    @property
    def robot(self) -> Any:
        return self.rt.robot

    @property
    def disk_dir(self) -> Path:
        """The folder that holds the program's disk files (FOPENW ...)."""
        return self.rt.disk.root

    @property
    def controller(self) -> Any:
        return getattr(self.rt.robot, "controller", None)

    @property
    def signals(self) -> dict[int, bool]:
        return self.rt.signals

    def task(self, num: int) -> Task | None:
        return self.rt.tasks.get(num)

    @property
    def programs(self) -> list[str]:
        return sorted(set(self.rt.programs) | set(self.rt.not_executable))

    # -- running in virtual time --------------------------------------------------------------------------
    def call(self, program: str, *args: Any, task: int = 0, attach: bool = False,
             max_time_s: float | None = None) -> CallResult:
        """CALL ``program`` with ``args`` in ``task`` (virtual time); return the arguments after the call.

        A Python number or string is passed as a variable the program may change (read it back in
        ``result.args``); a list or dict is passed as an array. Other tasks run meanwhile. Raises
        :class:`VPlusError` if the program stops with an error, ``TimeoutError`` after ``max_time_s`` of virtual
        time. ``attach``: the task has the robot attached (as after ``ATTACH ()``; task 0 always has).
        """
        if not self.clock.virtual:
            raise RuntimeError("Emulator.call runs in virtual time; use serve() in real time")
        boxes: list[Any] = []
        for a in args:
            if isinstance(a, dict):
                boxes.append({k: _to_vplus(v) for k, v in a.items()})
            elif isinstance(a, (list, tuple)):
                boxes.append({i: _to_vplus(v) for i, v in enumerate(a)})
            else:
                boxes.append(([_to_vplus(a)], 0))
        name = norm(program)
        T = self.rt.start_task(task, name, tuple(boxes))
        if attach and self.rt.robot is not None:
            self.rt.robot.attach(task)
            T.robot_attached = True
        deadline = None if max_time_s is None else self.rt.now + max_time_s
        self.rt.run_virtual(lambda: T.state != "running", max_time_s=deadline)
        if T.state == "running":
            self.rt.abort(task)
            raise TimeoutError(f"{program} still running after {max_time_s} s of virtual time")
        if T.state == "error":
            assert T.error is not None
            raise T.error
        out = tuple(b if isinstance(b, dict) else b[0][0] for b in boxes)
        return CallResult(out, task, self.rt.now)

    def execute(self, task: int, program: str, *args: Any, cycles: int = 1) -> Task:
        """EXECUTE ``program`` in ``task`` (it runs when time runs: :meth:`run`, :meth:`call`, :meth:`serve`)."""
        return self.rt.start_task(task, norm(program), tuple(([_to_vplus(a)], 0) for a in args), cycles=cycles)

    def run(self, seconds: float | None = None, *, until: Callable[[], bool] | None = None) -> None:
        """Run the tasks in virtual time for ``seconds`` (or until ``until()`` or no task is active)."""
        end = None if seconds is None else self.rt.now + seconds
        self.rt.run_virtual(until, max_time_s=end)
        if end is not None and self.rt.now < end:
            self.clock.now = end

    def abort(self, task: int) -> None:
        self.rt.abort(task)

    def set_tracer(self, tracer: Any, *, all_lines: bool = False) -> None:
        """Call ``tracer`` at V+ lines and errors (the API: :mod:`aioadept.vplus.trace`); before tasks start."""
        self.rt.set_tracer(tracer, all_lines=all_lines)

    def proceed(self, task: int) -> None:
        """PROCEED a task stopped by PAUSE."""
        T = self.rt.tasks.get(task)
        if T is not None and T.paused:
            T.paused = False
            T.wake = self.rt.now

    def feed_input(self, *lines: str) -> None:
        """Terminal input for PROMPT."""
        self.rt.input.extend(lines)

    # -- running in real time -------------------------------------------------------------------------------
    async def serve(self, stop: asyncio.Event) -> None:
        """Run the tasks on the asyncio loop, in real time, until ``stop`` is set (needs a :class:`RealClock`)."""
        await _RealTime(self.rt, stop).serve()


BURST_S = 0.002
"""Longest run of scheduler rounds in :meth:`Emulator.serve` before asyncio serves the sockets."""


class _RealTime:
    """One :meth:`Emulator.serve`: the scheduler's rounds on the asyncio loop.

    While every task waits, the loop sleeps on one future (``sleeper``): a wake-up (I/O, EXECUTE, SET.EVENT), the
    next task's wake time or ``stop`` completes it. (An asyncio.Event and asyncio.wait over two new tasks cost
    several loop turns and task creations per sleep: a large part of a round trip.)
    """

    def __init__(self, rt: Runtime, stop: asyncio.Event) -> None:
        self.rt = rt
        self.stop = stop
        self.loop = asyncio.get_running_loop()
        self.sleeper: asyncio.Future | None = None
        self.armed: float | None = None     # the runtime time the sleeping loop's timer is set for
        self.failed: list[BaseException] = []

    async def serve(self) -> None:
        rt = self.rt
        loop = self.loop
        stop = self.stop
        rt.on_wake = self.wake
        stopper = asyncio.ensure_future(stop.wait())
        stopper.add_done_callback(lambda _: self.wake())
        try:
            while not stop.is_set():
                if rt.any_ready():
                    self.burst()
                    await asyncio.sleep(0)
                    continue
                if rt.devices is not None:
                    rt.devices.flush()
                w = rt.next_wake()
                f = self.sleeper = loop.create_future()
                self.armed = w
                timer = None if w is None else loop.call_at(loop.time() + max(0.0, w - rt.now), self.on_timer)
                try:
                    await f
                finally:
                    self.sleeper = None
                    self.armed = None
                    if timer is not None:
                        timer.cancel()
                if self.failed:
                    raise self.failed[0]
        finally:
            rt.on_wake = None
            stopper.cancel()

    def burst(self) -> None:
        # Rounds back to back while tasks are ready (a reader handing a line to the executor and the
        # executor's ack back to the reader take three), then let asyncio serve the sockets: writes leave at
        # once (transport.write), reads and new connections wait for this yield.
        # Each round's writes leave right after it (an ack written by the reader does not wait for the
        # executor's re-test of its WAIT in the next round): latency, not CPU.
        # At most BURST_S of rounds before the sockets are served: a task kept busy by one client's flood
        # must not hold another client's stop in the kernel (32 rounds of a busy reader took 300 ms; a stop
        # behind them waited that long).
        rt = self.rt
        devices = rt.devices
        until = self.loop.time() + BURST_S
        for _ in range(32):
            rt.run_round()
            if devices is not None and devices.pending:
                devices.flush()
            if not rt.any_ready() or self.loop.time() >= until:
                break

    def wake(self) -> None:
        f = self.sleeper
        if f is None or f.done():
            return
        rt = self.rt
        if not self.stop.is_set() and rt.any_ready():
            # The loop is parked in ``await f``: run the woken tasks now, inside the I/O callback that woke
            # them (an ack leaves one event-loop turn sooner: the turn and the task wake-up were a tenth of a
            # here round trip). A wake-up from within these rounds (SET.EVENT) finds no sleeper.
            self.sleeper = None
            try:
                self.burst()
            except BaseException as exc:  # noqa: BLE001 - re-raised by serve, not by the I/O callback
                self.failed.append(exc)
            else:
                w = rt.next_wake()
                if not rt.any_ready() and (w is None or (self.armed is not None and w >= self.armed)):
                    # every task waits again, none before the loop's timer: the loop sleeps on (waking it
                    # to arm the same sleep again was most of a round trip's work after its ack)
                    self.sleeper = f
                    return
        f.set_result(None)

    def on_timer(self) -> None:
        self.armed = None
        f = self.sleeper
        if f is not None and not f.done():
            f.set_result(None)


def make_robot(controller: Any = None) -> Any:
    """The emulator's robot: a :class:`aioadept.vplus.robot.RobotDevice` on a sim Controller."""
    from aioadept.sim.controller import Controller
    from aioadept.vplus.robot import RobotDevice

    return RobotDevice(controller if controller is not None else Controller())


__all__ = ["CallResult", "Emulator", "GlobalsView", "LoadError", "RealClock", "VirtualClock", "VPlusError",
           "make_robot"]
