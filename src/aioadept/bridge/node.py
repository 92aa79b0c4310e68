"""The robot bridge node: ONE connection to a controller, shared by several applications over Zenoh.

Where it sits: ``aioadept bridge`` (:mod:`aioadept.cli.bridge`) runs it between a RobotServer (the V+ AdeptServer,
``aioadept sim`` or the V+ emulator) and any number of :class:`~aioadept.bridge.client.BridgeClient` s::

    app A ─┐  Zenoh query  aioadept/<cell>/<robot>/cmd   ┌────────┐  TCP (one RobotClient, + stop port)
    app B ─┼──────────────────────────────────────────▶│ Bridge │─────────────────────────▶ controller
    app C ─┘  ◀── state: aioadept/<cell>/<robot>/state  └────────┘  ◀── state stream (ZeroMQ) relayed

The safety rules it keeps (docs/bridge.md; each has a test in tests/integration/test_bridge.py):

- One writer: every batch goes through the bridge's one :class:`~aioadept.client.RobotClient`; batches run one
  at a time in arrival order (the controller runs one skill task anyway), so nothing waits on the controller's
  queue that the bridge could still withdraw.
- IDs: the RobotClient allocates the controller-side IDs; the acks go back with the application's own IDs, so two
  applications using the same IDs never collide.
- ``stop`` from any application is written at once (:meth:`RobotClient.stop_nowait`, in the loop turn the query
  arrives), past every queued batch; the controller aborts the batch in flight (its owner gets the ``aborted``
  acks) and every queued batch of every application is answered ``aborted`` and never sent.
- An application whose liveliness token vanishes gets its queued batches dropped, never sent; a batch of it
  already on the controller runs to its end (the protocol has no "withdraw one message", and a ``stop`` would
  abort the other applications' motions too).
- A malformed query gets an ``err`` reply (``malformed``) and changes nothing.
- One bridge per name: before it connects to the controller the bridge claims ``aioadept/<cell>/<robot>`` with a
  liveliness token and refuses to start (:class:`~aioadept.bridge.claim.BridgeNameTaken`) if Zenoh shows another
  bridge's claim or node token for that name (:mod:`aioadept.bridge.claim`); a query goes to one bridge only (the
  queryable is ``complete``, the client's target ``BEST_MATCHING``), so even two bridges never both run one command
  (docs/bridge.md, "One bridge per name").
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Any

from aioadept.bridge.claim import NameClaim, new_claim
from aioadept.bridge.wire import (
    MAX_QUEUED_PER_APP,
    MAX_QUEUED_TOTAL,
    BridgeFailure,
    BridgeRequest,
    apps_key,
    bridge_key,
    cmd_key,
    encode_failure,
    parse_request,
    state_key,
)
from aioadept.errors import MalformedRequest
from aioadept.client import RobotClient
from aioadept.errors import (
    AckTimeout,
    ClientStateError,
    CommandAborted,
    CommandError,
    ConnectError,
    ConnectionLost,
)
from aioadept.protocol import encode_ack

__all__ = ["Bridge", "BridgeStats", "MAX_APPS_TRACKED"]

MAX_APPS_TRACKED = 1024
"""At most this many live application names are kept in :attr:`Bridge.apps` (information only: an application's
batches are dropped when its token vanishes whether it is in the set or not)."""
_DRAIN_TURN = 64
"""Queries read per turn of the loop (besides every stop waiting)."""
_UNREAD_FULL = encode_failure(BridgeFailure("full", f"the bridge has {MAX_QUEUED_TOTAL} queries not yet read; "
                                                  "not sent"))

log = logging.getLogger("aioadept.bridge")


@dataclass
class BridgeStats:
    """What the bridge did, for tests and the log."""

    batches: int = 0
    stops: int = 0
    malformed: int = 0
    aborted_before_send: int = 0
    dropped_vanished: int = 0
    busy: int = 0
    full: int = 0


@dataclass
class _Job:
    req: BridgeRequest
    query: Any
    answered: bool = False


@dataclass
class Bridge:
    """Serve ``robot`` (a connected-or-not :class:`RobotClient`) as ``aioadept/<cell>/<name>`` on this process's
    Zenoh session (:func:`aioadept.bus.zenoh.session`, configured by the caller).

    ``async with Bridge(robot, cell="demo", name="robot") as bridge: await bridge.taken.wait()``. Entering raises
    :class:`~aioadept.bridge.claim.BridgeNameTaken` (before connecting to the controller) when another bridge has
    the name; ``taken`` is set when one that started earlier turns up later (two Zenoh networks joined): this bridge
    has then stopped serving and says why in ``taken_reason``. ``state_endpoint``: the controller's ZeroMQ state stream to relay onto
    ``aioadept/<cell>/<name>/state`` (``None``: no relay). ``claim_timeout_s``: how long the start waits for Zenoh's
    answer on the claims already there.
    """

    robot: RobotClient
    cell: str = "demo"
    name: str = "robot"
    state_endpoint: str | None = None
    claim_timeout_s: float = 2.0
    stats: BridgeStats = field(default_factory=BridgeStats)

    def __post_init__(self) -> None:
        self._key = cmd_key(self.cell, self.name)
        self._jobs: deque[_Job] = deque()
        self._more = asyncio.Event()
        self._current: _Job | None = None
        self._queued: dict[str, int] = {}  # application -> its batches in _jobs
        self._stop_gen = 0  # stops so far: a batch taken from the queue before a stop is never sent after it
        self._loop: asyncio.AbstractEventLoop | None = None
        self._entities: list[Any] = []
        self._tasks: list[asyncio.Task[None]] = []
        self._closing = False  # no more queries taken
        self._closed = False
        self.apps: set[str] = set()
        """Applications whose liveliness token is alive (at most :data:`MAX_APPS_TRACKED` of them)."""
        # Queries handed over by Zenoh's threads, read by the loop in turns (_drain): stops first, at most
        # _DRAIN_TURN others per turn, so a stop never waits behind a flood of queries not yet read.
        self._inbox: deque[tuple[Any, bytes, bytes | None]] = deque()
        self._urgent: deque[tuple[Any, bytes, bytes | None]] = deque()
        self._inbox_lock = threading.Lock()
        self._drain_scheduled = False
        self.claim = new_claim()
        """This bridge's claim on the name (:mod:`aioadept.bridge.claim`)."""
        self._queryable: Any = None
        self.taken = asyncio.Event()
        self.taken_reason = ""

    # ------------------------------------------------------------------------------------------ lifecycle
    async def __aenter__(self) -> Bridge:
        from aioadept.bus import zenoh as zb

        zenoh = zb._zenoh()
        self._loop = asyncio.get_running_loop()
        s = zb.session()
        try:
            name_claim = NameClaim(self.cell, self.name, self.claim, self._entities, self._back_off)
            # Before the controller: a second bridge never even connects.
            await name_claim.take(s, zenoh, self.claim_timeout_s)
            if not self.robot.connected:
                await self.robot.connect()
            # complete=True: a query (target BEST_MATCHING, the client's) goes to ONE complete queryable, so even
            # two bridges on one name (two Zenoh networks joined) never both run a command.
            self._queryable = s.declare_queryable(
                self._key, zenoh.handlers.Callback(self._on_query_thread, indirect=True), complete=True)
            self._entities.append(self._queryable)
            self._entities.append(s.liveliness().declare_subscriber(
                apps_key(self.cell, self.name), zenoh.handlers.Callback(self._on_presence_thread), history=True))
        except BaseException:
            await self._undeclare()
            await self.robot.close()
            raise
        self._tasks.append(self._loop.create_task(self._pump(), name=f"bridge {self._key}"))
        if self.state_endpoint is not None:
            self._tasks.append(self._loop.create_task(self._relay_state(), name=f"bridge state {self._key}"))
        name_claim.serve(s)
        # Last: applications waiting for the bridge see it once it serves.
        self._entities.append(zb.declare_node(self.cell, self.name))
        return self

    def _back_off(self, claim: str) -> None:
        """An earlier bridge serves this name too (two Zenoh networks joined): stop taking queries now, answer the
        queued ones ``closed`` (never sent); the batch in flight runs to its end. The owner ends the process."""
        if self.taken.is_set():
            return
        self.taken_reason = (f"another bridge (claim {claim}, started before this one's {self.claim}) serves the "
                             f"robot name {bridge_key(self.cell, self.name)}: this bridge stopped serving")
        log.error("bridge %s: %s", self._key, self.taken_reason)
        if self._queryable is not None:
            try:
                self._queryable.undeclare()
            except Exception as exc:
                log.debug("undeclare: %r", exc)
        self._closing = True
        jobs, self._jobs = self._jobs, deque()
        self._queued.clear()
        for job in jobs:
            self._fail(job, BridgeFailure("closed", "this bridge gave the robot name up; not sent"))
        self.taken.set()

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        """Answer every queued batch ``closed`` (never sent), stop serving, close the controller link."""
        if self._closed:
            return
        self._closed = self._closing = True
        with self._inbox_lock:
            unread = [*self._urgent, *self._inbox]
            self._urgent.clear()
            self._inbox.clear()
        for query, _, _ in unread:
            self._reply_err(query, BridgeFailure("closed", "the bridge is shutting down; not sent"))
        for job in self._jobs:
            self._fail(job, BridgeFailure("closed", "the bridge is shutting down; not sent",
                                          unresolved=()))
        self._jobs.clear()
        current = self._current
        for t in self._tasks:
            t.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        if current is not None and not current.answered:  # it was on the controller: its fate is unknown
            self._fail(current, BridgeFailure("lost", "the bridge shut down before the acks",
                                              unresolved=current.req.ids))
        await self._undeclare()
        await self.robot.close()

    async def _undeclare(self) -> None:
        for e in reversed(self._entities):
            try:
                e.undeclare()
            except Exception as exc:  # already gone with the session
                log.debug("undeclare: %r", exc)
        self._entities.clear()

    # ------------------------------------------------------------------------------------------ queries
    def _on_query_thread(self, query: Any) -> None:
        # On a Zenoh thread: copy the bytes and put the query in the inbox (a stop in the urgent one), nothing else.
        loop = self._loop
        if loop is None:
            return
        payload = query.payload.to_bytes() if query.payload is not None else b""
        att = query.attachment.to_bytes() if query.attachment is not None else None
        # A guess, to read it first; parse_request decides what it is.
        urgent = b":stop" in payload and payload.count(b"\n") <= 1
        with self._inbox_lock:
            if not urgent and len(self._inbox) >= MAX_QUEUED_TOTAL:
                full = True
            else:
                full = False
                (self._urgent if urgent else self._inbox).append((query, payload, att))
                schedule, self._drain_scheduled = not self._drain_scheduled, True
        if full:  # the loop is behind: refuse here, keeping nothing
            self.stats.full += 1
            try:
                query.reply_err(_UNREAD_FULL)
            except Exception as exc:
                log.debug("error reply on %s: %r", self._key, exc)
            finally:
                query.drop()
            return
        if schedule:
            try:
                loop.call_soon_threadsafe(self._drain)
            except RuntimeError:  # the loop is closed
                pass

    def _drain(self) -> None:
        """A turn of the loop: every stop waiting, then at most _DRAIN_TURN other queries; again next turn if more."""
        for _ in range(_DRAIN_TURN):
            with self._inbox_lock:
                box = self._urgent or self._inbox
                if not box:
                    self._drain_scheduled = False
                    return
                query, payload, att = box.popleft()
            self._on_query(query, payload, att)
        assert self._loop is not None
        self._loop.call_soon(self._drain)

    def _on_query(self, query: Any, payload: bytes | None = None, att: bytes | None = None) -> None:
        if self._closing:
            self._reply_err(query, BridgeFailure("closed", "the bridge is shutting down; not sent"))
            return
        try:
            if payload is None:
                payload = query.payload.to_bytes() if query.payload is not None else b""
                att = query.attachment.to_bytes() if query.attachment is not None else None
            req = parse_request(payload, att)
        except MalformedRequest as exc:
            self.stats.malformed += 1
            log.warning("bridge %s: malformed query refused: %s", self._key, exc)
            self._reply_err(query, BridgeFailure("malformed", str(exc)))
            return
        if req.is_stop:
            self._stop(req, query)
            return
        if len(self._jobs) >= MAX_QUEUED_TOTAL:
            self.stats.full += 1
            self._reply_err(query, BridgeFailure("full", f"the bridge already holds {len(self._jobs)} batches of all "
                                                         "applications waiting; not sent"))
            return
        n = self._queued.get(req.app, 0)
        if n >= MAX_QUEUED_PER_APP:
            self.stats.busy += 1
            self._reply_err(query, BridgeFailure("busy", f"application {req.app!r} already has {n} batches "
                                                         "waiting in the bridge; not sent"))
            return
        self._queued[req.app] = n + 1
        self._jobs.append(_Job(req, query))
        self._more.set()

    def _stop(self, req: BridgeRequest, query: Any) -> None:
        """A stop from ``req.app``: written now, before anything queued; the queued batches are answered."""
        self.stats.stops += 1
        self._stop_gen += 1
        task = self.robot.stop_nowait()  # connected: written before this returns
        log.warning("bridge %s: stop from application %r (%d queued batch(es) not sent)", self._key, req.app,
                    len(self._jobs))
        jobs, self._jobs = self._jobs, deque()
        self._queued.clear()
        for job in jobs:
            self.stats.aborted_before_send += 1
            self._fail(job, BridgeFailure("aborted", f"stop from application {req.app!r} before it was sent"))

        def done(t: asyncio.Task[Any]) -> None:
            if t.cancelled():
                self._reply_err(query, BridgeFailure("closed", "the bridge closed before the stop's ack",
                                                     unresolved=req.ids))
                return
            exc = t.exception()
            if exc is None:
                self._reply_ok(query, encode_ack(replace(t.result().ack, id=req.ids[0])))
            else:
                self._reply_err(query, _failure_of(exc, req.ids, {}))

        task.add_done_callback(done)

    def _on_presence_thread(self, sample: Any) -> None:
        from aioadept.bus import zenoh as zb

        app = str(sample.key_expr).rsplit("/", 1)[-1]
        alive = sample.kind == zb._zenoh().SampleKind.PUT
        loop = self._loop
        if loop is not None:
            try:
                loop.call_soon_threadsafe(self._on_presence, app, alive)
            except RuntimeError:
                pass

    def _on_presence(self, app: str, alive: bool) -> None:
        if alive:
            if len(self.apps) < MAX_APPS_TRACKED:
                self.apps.add(app)
            return
        self.apps.discard(app)
        gone = [j for j in self._jobs if j.req.app == app]
        if gone:
            self._jobs = deque(j for j in self._jobs if j.req.app != app)
            self._queued.pop(app, None)
            for job in gone:
                self.stats.dropped_vanished += 1
                self._fail(job, BridgeFailure("dropped", f"application {app!r} vanished; not sent"))
        running = self._current is not None and self._current.req.app == app
        if not gone and not running:
            log.info("bridge %s: application %r left with nothing queued", self._key, app)
            return
        log.warning("bridge %s: application %r vanished: %d queued batch(es) dropped, never sent%s", self._key,
                    app, len(gone), "; its batch on the controller runs to its end" if running else "")

    # ------------------------------------------------------------------------------------------ the writer
    async def _pump(self) -> None:
        """The one writer: batches in arrival order, one at a time."""
        while True:
            while not self._jobs:
                self._more.clear()
                await self._more.wait()
            job = self._jobs.popleft()
            left = self._queued.get(job.req.app, 1) - 1
            if left > 0:
                self._queued[job.req.app] = left
            else:
                self._queued.pop(job.req.app, None)
            self._current = job
            try:
                await self._execute(job)
            finally:
                self._current = None

    async def _execute(self, job: _Job) -> None:
        req = job.req
        robot = self.robot
        self.stats.batches += 1
        gen = self._stop_gen
        if not robot.connected:
            try:  # a lost controller link: reconnect for the NEXT batch (nothing is ever re-sent)
                await robot.connect()
            except (ConnectError, ClientStateError) as exc:
                self._fail(job, BridgeFailure("lost", f"controller not connected, not sent: {exc}"))
                return
        if self._stop_gen != gen:  # a stop came while we reconnected: as if it had been queued
            self.stats.aborted_before_send += 1
            self._fail(job, BridgeFailure("aborted", "a stop came before it was sent"))
            return
        try:
            sub = robot.submit(*req.calls)
        except (ConnectionLost, ClientStateError) as exc:
            self._fail(job, BridgeFailure("lost", f"controller not connected, not sent: {exc}"))
            return
        to_app = dict(zip(sub.ids, req.ids, strict=True))
        try:
            results = await sub.wait()
        except (CommandError, CommandAborted) as exc:
            results = exc.results  # type: ignore[union-attr]
        except (ConnectionLost, AckTimeout) as exc:
            self._fail(job, _failure_of(exc, req.ids, to_app))
            return
        job.answered = True
        self._reply_ok(job.query, b"".join(encode_ack(replace(r.ack, id=to_app[r.id])) for r in results))

    # ------------------------------------------------------------------------------------------ replies
    def _reply_ok(self, query: Any, payload: bytes) -> None:
        try:
            query.reply(self._key, payload)
        except Exception as exc:  # the application is gone: nobody to tell
            log.debug("reply on %s: %r", self._key, exc)
        finally:
            query.drop()

    def _reply_err(self, query: Any, failure: BridgeFailure) -> None:
        try:
            query.reply_err(encode_failure(failure))
        except Exception as exc:
            log.debug("error reply on %s: %r", self._key, exc)
        finally:
            query.drop()

    def _fail(self, job: _Job, failure: BridgeFailure) -> None:
        job.answered = True
        self._reply_err(job.query, failure)

    # ------------------------------------------------------------------------------------------ state
    async def _relay_state(self) -> None:
        """The controller's state publications, frame for frame, onto ``aioadept/<cell>/<name>/state``."""
        import zmq
        import zmq.asyncio

        from aioadept.bus.zenoh import PREFIX
        from aioadept.bus.zenohsocket import make_zenoh_socket

        ctx = zmq.asyncio.Context.instance()
        sub = ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.SUBSCRIBE, b"")
        sub.setsockopt(zmq.LINGER, 0)
        pub = make_zenoh_socket(zmq.PUB, PREFIX + state_key(self.cell, self.name))
        try:
            sub.connect(self.state_endpoint)
            pub.declare()
            while True:
                frames = await sub.recv_multipart()
                if len(frames) in (1, 2):
                    pub.send_multipart(frames)
        except asyncio.CancelledError:
            raise
        except Exception as exc:  # the commands go on being served without the relay; say so once
            log.error("bridge %s: the state relay from %s stopped: %s", self._key, self.state_endpoint, exc)
        finally:
            sub.close()
            pub.close()


def _failure_of(exc: BaseException, app_ids: tuple[str, ...], to_app: dict[str, str]) -> BridgeFailure:
    """The ``err`` reply for a RobotClient failure, controller IDs mapped back to the application's."""
    def ids(cids: tuple[str, ...]) -> tuple[str, ...]:
        return tuple(to_app.get(c, c) for c in cids if c in to_app)

    if isinstance(exc, ConnectionLost):
        # Its text without its own ID lists: those are the controller's IDs, the reply carries the application's.
        reason = str(exc).split("; acked=")[0]
        return BridgeFailure("lost", f"controller link lost: {reason}", ids(exc.acked), ids(exc.unresolved))
    if isinstance(exc, AckTimeout):
        return BridgeFailure("timeout", f"controller gave no ack in time: {exc}", (),
                             ids(tuple(exc.pending)) or app_ids)
    return BridgeFailure("lost", f"{type(exc).__name__}: {exc}", (), app_ids)
