"""BridgeClient: an application's side of the robot bridge, with RobotClient's call API.

Where it sits: an application (the focus app, a script) uses it instead of :class:`~aioadept.client.RobotClient`
when the robot is shared through ``aioadept bridge`` (:mod:`aioadept.bridge.node`)::

    async with BridgeClient(cell="demo", robot="robot", app="focus") as rc:
        await rc.cmdexec(MoveJoints([0, -90, 180, 0, 90, 0]))
        await rc.stop()

Each command (``cmdexec``) or call (``cmdexec_joined``, ``here``, ``hello``, ``status``) is one Zenoh query on
``aioadept/<cell>/<robot>/cmd`` carrying its wire lines with this application's IDs (:mod:`aioadept.bridge.wire`);
the reply carries the acks. Results and errors are RobotClient's: :class:`ExecResult`, :class:`CommandError`,
:class:`CommandAborted` (a stop from any application aborted the batch on the controller),
:class:`AbortedBeforeSend` (a stop came while the batch was queued in the bridge: never sent),
:class:`ConnectionLost` (``acked`` / ``unresolved``: the controller link or the bridge itself went away),
:class:`AckTimeout`, :class:`TooManyPending` (this application already has 64 batches waiting in the bridge, or
the bridge 256 of all applications; nothing sent) and :class:`BridgeRefused` for a query the bridge would not take.

While connected the client holds a liveliness token ``aioadept/<cell>/<robot>/apps/<app>``: when this process
ends, the bridge drops this application's batches not yet sent. It also watches the bridge's own token: when the
bridge vanishes every pending call fails at once with :class:`ConnectionLost` naming what is known done.
"""

from __future__ import annotations

import asyncio
import logging
import os
import secrets
from collections.abc import Iterable
from typing import Any

from aioadept.bridge.wire import (
    MAX_QUEUED_PER_APP,
    MAX_QUEUED_TOTAL,
    BridgeFailure,
    app_key,
    bridge_key,
    cmd_key,
    encode_request,
    parse_failure,
)
from aioadept.client.registry import calls_of, check_timeout
from aioadept.client.results import ExecResult, MessageResult, Observer, SentMessage
from aioadept.commands import Command
from aioadept.errors import (
    AbortedBeforeSend,
    AckTimeout,
    AdeptError,
    BridgeRefused,
    ClientStateError,
    CommandAborted,
    CommandError,
    ConnectError,
    ConnectionLost,
    TooManyPending,
)
from aioadept.geometry import Pose
from aioadept.protocol import HELLO_SKILL, HERE_SKILL, STOP_SKILL, IdAllocator, SkillCall, Status, parse_ack
from aioadept.protocol.robotstatus import STATUS_SKILL, RobotStatus, parse_status_fields

__all__ = ["BridgeClient"]

log = logging.getLogger("aioadept.bridge")

_MARGIN_S = 5.0
"""The Zenoh query outlives the ack wait by this much, so the bridge's own timeout answer arrives first."""


class BridgeClient:
    """RobotClient's API (``cmdexec``, ``cmdexec_joined``, ``stop``, ``here``, ``hello``, ``status``) through a
    robot bridge. Uses this process's Zenoh session (configure it first: :func:`aioadept.bus.zenoh.configure`).

    - ``app``: this application's name (default ``app-<pid>-<random>``); unique per bridge.
    - ``connect_timeout_s``: how long :meth:`connect` waits for the bridge's token (→ :class:`ConnectError`).
    - ``ack_timeout_s`` / ``stop_timeout_s``: as RobotClient's (a call waits at most that + the bridge's hop).
    """

    def __init__(self, cell: str = "demo", robot: str = "robot", *, app: str | None = None,
                 connect_timeout_s: float = 5.0, ack_timeout_s: float | None = 60.0, stop_timeout_s: float = 5.0,
                 observers: Iterable[Observer] = (), id_start: int | None = None) -> None:
        self.cell = cell
        self.robot = robot
        self.app = app or f"app-{os.getpid()}-{secrets.token_hex(2)}"
        self._key = cmd_key(cell, robot)
        self._app_key = app_key(cell, robot, self.app)  # checks the names
        self.connect_timeout_s = check_timeout("connect_timeout_s", connect_timeout_s, none_ok=False)
        self.ack_timeout_s = check_timeout("ack_timeout_s", ack_timeout_s)
        self.stop_timeout_s = check_timeout("stop_timeout_s", stop_timeout_s, none_ok=False)
        self._observers = list(observers)
        self._ids = IdAllocator(secrets.randbits(32) if id_start is None else id_start)
        self._token: Any = None
        self._watch: Any = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._bridge_alive = asyncio.Event()
        self._pending: dict[int, tuple[asyncio.Future[Any], tuple[str, ...]]] = {}
        self._batches = 0
        self._lost: str | None = None

    # ------------------------------------------------------------------------------------------ lifecycle
    @property
    def connected(self) -> bool:
        return self._token is not None and self._lost is None

    def add_observer(self, observer: Observer) -> None:
        self._observers.append(observer)

    def remove_observer(self, observer: Observer) -> None:
        self._observers.remove(observer)

    async def __aenter__(self) -> BridgeClient:
        await self.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def connect(self) -> None:
        """Declare this application and wait for the bridge's token (:class:`ConnectError` after
        ``connect_timeout_s``)."""
        from aioadept.bus import zenoh as zb

        if self._token is not None:
            raise ClientStateError(f"already connected to the bridge {self._key}")
        zenoh = zb._zenoh()
        self._loop = asyncio.get_running_loop()
        self._bridge_alive = asyncio.Event()
        self._lost = None
        s = zb.session()
        self._watch = s.liveliness().declare_subscriber(
            bridge_key(self.cell, self.robot), zenoh.handlers.Callback(self._on_bridge_thread), history=True)
        self._token = s.liveliness().declare_token(self._app_key)
        try:
            async with asyncio.timeout(self.connect_timeout_s):
                await self._bridge_alive.wait()
        except TimeoutError:
            await self.close()
            raise ConnectError(f"no robot bridge {bridge_key(self.cell, self.robot)} within "
                               f"{self.connect_timeout_s:g} s (is 'aioadept bridge --cell {self.cell} --name "
                               f"{self.robot}' running on the same Zenoh router?)") from None

    async def close(self) -> None:
        """Undeclare this application (the bridge drops its batches not yet sent); pending calls fail with
        :class:`ConnectionLost`. Idempotent."""
        self._fail_pending("client closed")
        for e in (self._token, self._watch):
            if e is not None:
                try:
                    e.undeclare()
                except Exception:
                    pass
        self._token = self._watch = None

    def _on_bridge_thread(self, sample: Any) -> None:
        from aioadept.bus import zenoh as zb

        alive = sample.kind == zb._zenoh().SampleKind.PUT
        loop = self._loop
        if loop is not None:
            _hand_over(loop, self._on_bridge, alive)

    def _on_bridge(self, alive: bool) -> None:
        if alive:
            self._lost = None
            self._bridge_alive.set()
            return
        self._bridge_alive.clear()
        self._lost = f"the robot bridge {bridge_key(self.cell, self.robot)} vanished"
        log.warning("%s with %d call(s) pending", self._lost, len(self._pending))
        self._fail_pending(self._lost)

    def _fail_pending(self, why: str) -> None:
        for fut, _ in list(self._pending.values()):
            if not fut.done():
                fut.set_result(("gone", why))

    # ------------------------------------------------------------------------------------------ one query
    async def _query(self, calls: tuple[SkillCall, ...], timeout_s: float | None) -> tuple[MessageResult, ...]:
        """One batch through the bridge: its results in order, or RobotClient's exceptions."""
        from aioadept.bus import zenoh as zb

        if self._token is None:
            raise ClientStateError(f"not connected to the bridge {self._key}")
        ids = tuple(self._ids.take(len(calls)))
        if self._lost is not None:
            raise ConnectionLost(f"{self._lost}; nothing was sent", unresolved=())
        loop = self._loop
        assert loop is not None
        self._batches += 1
        batch = self._batches
        fut: asyncio.Future[Any] = loop.create_future()
        replies: list[tuple[bool, bytes]] = []

        def on_reply(rep: Any) -> None:  # a Zenoh thread: copy the bytes, hand over
            ok = rep.ok is not None
            data = (rep.ok.payload if ok else rep.err.payload).to_bytes()
            _hand_over(loop, replies.append, (ok, data))

        def on_done() -> None:  # the query is finalized (all replies in, or none will come)
            _hand_over(loop, _settle, fut, ("done", None))

        self._pending[batch] = (fut, ids)
        wait_s = self.ack_timeout_s if timeout_s is None else timeout_s
        zenoh = zb._zenoh()
        t_send = loop.time()
        try:
            # indirect=False: both callbacks only copy and hand over, so they run on Zenoh's own thread; the default
            # (indirect) starts a Python thread for every query: here through the bridge p50 0.63 -> 0.49 ms.
            # BEST_MATCHING: the query goes to ONE complete queryable (the bridge declares its queryable complete),
            # never to every bridge on the key, so a command runs once even if two bridges serve one name.
            zb.session().get(self._key, zenoh.handlers.Callback(on_reply, on_done, indirect=False),
                             payload=encode_request(ids, calls), attachment=self.app.encode("ascii"),
                             target=zenoh.QueryTarget.BEST_MATCHING, timeout=(wait_s or 24 * 3600.0) + _MARGIN_S)
            for obs in self._observers:
                for mid, call in zip(ids, calls, strict=True):
                    _safe(obs.on_send, SentMessage(mid, call.skill, call.args, batch, t_send))
            try:
                async with asyncio.timeout(None if wait_s is None else wait_s + _MARGIN_S):
                    how, why = await fut
            except TimeoutError:
                raise AckTimeout(f"no answer from the bridge {self._key} within {wait_s} s for "
                                 f"{list(ids)}", pending=ids) from None
        finally:
            self._pending.pop(batch, None)
        t_recv = loop.time()
        if how == "gone":
            raise ConnectionLost(f"{why} before the answer", unresolved=ids)
        if not replies:
            raise ConnectionLost(f"the robot bridge {self._key} ended the query without an answer (gone?)",
                                 unresolved=ids)
        ok, data = replies[0]
        if not ok:
            raise _error_of(parse_failure(data), calls)
        return self._results(data, ids, calls, batch, t_send, t_recv)

    def _results(self, data: bytes, ids: tuple[str, ...], calls: tuple[SkillCall, ...], batch: int,
                 t_send: float, t_recv: float) -> tuple[MessageResult, ...]:
        by_id = {}
        for line in data.split(b"\r\n"):
            if line:
                ack = parse_ack(line)
                by_id[ack.id] = ack
        missing = [i for i in ids if i not in by_id]
        if missing:
            raise ConnectionLost(f"the bridge answered without acks for {missing}",
                                 acked=tuple(i for i in ids if i in by_id), unresolved=tuple(missing))
        results = tuple(MessageResult(mid, c.skill, c.args, batch, t_send, t_recv, by_id[mid])
                        for mid, c in zip(ids, calls, strict=True))
        for r in results:
            for obs in self._observers:
                _safe(obs.on_ack, r)
        for r in results:
            if r.ack.status is not Status.DONE:
                exc: CommandError | CommandAborted = (CommandError(r.ack, r.skill) if r.ack.status is Status.ERROR
                                                      else CommandAborted(r.ack, r.skill))
                exc.results = results  # type: ignore[union-attr]
                raise exc
        return results

    # ------------------------------------------------------------------------------------------ the API
    async def cmdexec(self, *commands: Command, timeout_s: float | None = None) -> ExecResult:
        """As :meth:`RobotClient.cmdexec`: one query per command, each awaited before the next is sent."""
        if timeout_s is not None:
            check_timeout("timeout_s", timeout_s)
        per_command = [calls_of((c,)) for c in commands]
        if not per_command:
            raise ValueError("commands: at least one command is required")
        messages: list[MessageResult] = []
        for k, calls in enumerate(per_command):
            try:
                messages.extend(await self._query(tuple(calls), timeout_s))
            except ConnectionLost as exc:
                done = tuple(m.id for m in messages)
                raise ConnectionLost(str(exc).split("; acked=")[0], acked=(*done, *exc.acked),
                                     unresolved=exc.unresolved) from exc
            except (CommandError, CommandAborted) as exc:
                exc.completed = ExecResult(tuple(messages), commands[:k],  # type: ignore[union-attr]
                                           tuple(len(c) for c in per_command[:k]))
                raise
        return ExecResult(tuple(messages), commands, tuple(len(c) for c in per_command))

    async def cmdexec_joined(self, *commands: Command, timeout_s: float | None = None) -> ExecResult:
        """As :meth:`RobotClient.cmdexec_joined`: every message in one query (one batch on the controller)."""
        if timeout_s is not None:
            check_timeout("timeout_s", timeout_s)
        per_command = [calls_of((c,)) for c in commands]
        calls = tuple(c for cs in per_command for c in cs)
        if not calls:
            raise ValueError("commands: nothing to send")
        results = await self._query(calls, timeout_s)
        return ExecResult(results, commands, tuple(len(c) for c in per_command))

    async def stop(self, *, timeout_s: float | None = None) -> MessageResult:
        """Stop the robot: the bridge writes it at once, past every application's queued batches, which fail
        (:class:`CommandAborted` / :class:`AbortedBeforeSend`). Returns the stop's result on its ``done`` ack."""
        t = self.stop_timeout_s if timeout_s is None else check_timeout("timeout_s", timeout_s, none_ok=False)
        return (await self._query((_STOP,), t))[0]

    async def here(self, *, timeout_s: float | None = None) -> Pose:
        return (await self._query((_HERE,), timeout_s))[0].ack.pose

    async def hello(self, *, timeout_s: float | None = None) -> tuple[int | None, str]:
        ack = (await self._query((_HELLO,), timeout_s))[0].ack
        try:
            version: int | None = int(ack.extra[0])
        except (IndexError, ValueError):
            version = None
        return version, (ack.extra[1] if len(ack.extra) > 1 else "")

    async def status(self, *, timeout_s: float | None = None) -> RobotStatus:
        return parse_status_fields((await self._query((_STATUS,), timeout_s))[0].ack.extra)

    def __repr__(self) -> str:
        return f"<BridgeClient {self.app} -> {self._key} pending={len(self._pending)}>"


_STOP = SkillCall(STOP_SKILL)
_HERE = SkillCall(HERE_SKILL)
_HELLO = SkillCall(HELLO_SKILL)
_STATUS = SkillCall(STATUS_SKILL)


def _hand_over(loop: asyncio.AbstractEventLoop, fn: Any, *args: Any) -> None:
    """From a Zenoh thread: run ``fn(*args)`` on ``loop``; nothing if the loop is closed (nobody waits any more)."""
    try:
        loop.call_soon_threadsafe(fn, *args)
    except RuntimeError:
        pass


def _settle(fut: asyncio.Future[Any], value: Any) -> None:
    if not fut.done():
        fut.set_result(value)


def _safe(fn: Any, arg: Any) -> None:
    try:
        fn(arg)
    except Exception:
        log.exception("observer %r failed", fn)


def _error_of(f: BridgeFailure, calls: tuple[SkillCall, ...]) -> AdeptError:
    """RobotClient's exception for a bridge ``err`` reply."""
    skill = calls[0].skill
    if f.kind == "aborted":
        exc = AbortedBeforeSend(skill)
        exc.args = (f"{skill} not sent: {f.text}",)
        return exc
    if f.kind == "dropped":
        return CommandAborted(None, skill, message=f"{skill} not sent: {f.text}")
    if f.kind == "lost":
        return ConnectionLost(f.text, acked=f.acked, unresolved=f.unresolved)
    if f.kind == "timeout":
        return AckTimeout(f.text, pending=f.unresolved)
    if f.kind == "busy":
        return TooManyPending(f.text, pending=MAX_QUEUED_PER_APP, wanted=len(calls), limit=MAX_QUEUED_PER_APP)
    if f.kind == "full":
        return TooManyPending(f"the robot bridge is full: {f.text}", pending=MAX_QUEUED_TOTAL, wanted=len(calls),
                              limit=MAX_QUEUED_TOTAL)
    return BridgeRefused(f"the robot bridge refused the query: {f.text}", kind=f.kind)
