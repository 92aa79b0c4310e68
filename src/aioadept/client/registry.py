"""PendingCalls: the client's sans-IO registry of messages written and not yet acked (the shape of h11's
``Connection``: events in, state out; no sockets, no asyncio, no clock).

Where it sits in the data path: :class:`~aioadept.client.RobotClient` asks it for a batch's IDs and wire bytes
(:meth:`PendingCalls.register`, *before* it writes them), feeds it every chunk it reads with the read time
(``PendingCalls.receive``: an :class:`~aioadept.protocol.AckReader` cuts the chunk into acks, each is routed to
its :class:`Submission`), and tells it when a waiter gives up (:meth:`PendingCalls.release`, in ``finally``) or
the connection drops (:meth:`PendingCalls.fail_all`: every pending submission learns which of its messages are
known done and which are unresolved). Unit tests drive it with bytes and read its state::

    reg = PendingCalls(id_start=1)
    sub, wire = reg.register([SkillCall("here")])       # wire == b"00000001:here\\r\\n", reg.pending_ids == ("00000001",)
    reg.receive(b"00000001:done:1.000,1.000:0,0,0,0,0,0\\r\\n", t_recv=5.0)
    assert sub.remaining == 0 and sub.results[0].ack.ok and reg.pending_ids == ()

A submission's waiter and per-message futures are whatever the owner puts there (asyncio futures in the client,
any object with ``done()`` / ``set_result()`` / ``set_exception()`` in a test): the registry only resolves them.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from aioadept.client.results import ClientStats, MessageResult, _make_result, _RESULT_TWIN
from aioadept.errors import ClientStateError, ConnectionLost
from aioadept.protocol import MAX_ACK_LINE, NO_ID, Ack, AckReader, IdAllocator, SkillCall, Status
from aioadept.protocol.reader import BadAck

__all__ = ["PendingCalls", "Submission", "check_timeout"]

_ABANDONED_MEMORY = 4096  # how many cancelled/timed-out IDs we remember to tell late acks from unknown ones
_DONE = Status.DONE
_ACK = Ack
_BAD = BadAck
W_ACKED = 0       # waiter results: why a batch's waiter woke up
W_TIMED_OUT = 1
W_LOST = 2


class Submission:
    """The messages written together in one write (one batch), and their state in the pending registry.

    Returned by :meth:`RobotClient.submit`. ``futures`` holds a future per message (only for ``submit``; the
    ``cmdexec`` path does without them): each resolves to a :class:`MessageResult` whatever the ack's status (so
    an ignored future never logs "exception never retrieved"), or fails with :class:`ConnectionLost`. :meth:`wait`
    turns statuses into errors and removes the messages from the registry; call it (or :meth:`cancel`) once.
    ``results`` (send order, ``None`` until acked) and ``remaining`` are its state.
    """

    # No __slots__: the rarely changed fields are class-level defaults, so creating one (per write, on the round
    # trip's critical path) sets only what every batch needs.
    futures: tuple[Any, ...] | None = None
    t_send_s = 0.0
    _owner: Any = None  # the RobotClient that waits on it (None: registry-only, e.g. in unit tests)
    _registry: PendingCalls
    _waiter: Any = None
    _deadline = 0.0
    _timer: Any = None
    _settled = False
    _lost_reason: str | None = None
    _first_bad = -1  # index of the first non-done ack (in send order), -1 if none
    _next_i = 0  # where the next ack is expected in ``ids`` (one after the previous ack's)

    def __init__(self, ids: tuple[str, ...], calls: Sequence[SkillCall], batch: int) -> None:
        self.ids = ids
        self.calls = calls
        self.batch = batch
        self.results: list[MessageResult | None] = [None] * len(ids)
        self.remaining = len(ids)

    def _index(self, mid: str) -> int:
        """The index of message ``mid`` (registered, so present); expected one after the previous ack's."""
        ids = self.ids
        i = self._next_i
        if i >= len(ids) or ids[i] != mid:
            i = ids.index(mid)
        self._next_i = i + 1
        return i

    def done(self) -> bool:
        """True when every message is acked or the connection was lost."""
        return self.remaining == 0 or self._lost_reason is not None

    @property
    def lost_reason(self) -> str | None:
        """Why the connection was lost before every ack came (None while it was not)."""
        return self._lost_reason

    async def wait(self, *, timeout_s: float | None = None) -> tuple[MessageResult, ...]:
        """All results in send order. Raises CommandError / CommandAborted (first failing message, after all
        acks are in; ``exc.results`` holds them), ConnectionLost, or AckTimeout (``timeout_s=None``: the client's
        ``ack_timeout_s``; else finite and > 0, or ValueError)."""
        if timeout_s is not None:
            check_timeout("timeout_s", timeout_s)
        if self._owner is None:
            raise ClientStateError("this submission has no client to wait with")
        return await self._owner._wait(self, timeout_s)  # type: ignore[no-any-return]

    def cancel(self) -> None:
        """Stop waiting: forget the messages (late acks are dropped and counted). The robot is not stopped."""
        if self._owner is not None:
            self._owner._release(self)
        else:
            self._registry.release(self)

    def __repr__(self) -> str:
        done = len(self.ids) - self.remaining
        return f"<Submission batch={self.batch} ids={list(self.ids)} acked={done}/{len(self.ids)}>"


_new_submission = object.__new__


class PendingCalls:
    """The one registry of pending messages (ID -> :class:`Submission`), the IDs and the ack reader of one client.

    ``id_start``: the first ID as an int (the client draws a random one). IDs count up, skip ``00000000``, and
    never repeat one still pending or given up (see :meth:`register`). ``on_result`` (a callable or None) sees
    every routed result; ``on_unexpected(kind, line, t_recv)`` every line that is not the ack of a pending message
    (kinds ``unknown_ack``, ``unroutable_error``, ``bad_line``, ``oversize``), after it is counted in ``stats``.
    """

    def __init__(self, *, id_start: int, max_line: int = MAX_ACK_LINE, stats: ClientStats | None = None) -> None:
        self.stats = stats if stats is not None else ClientStats()
        self.on_result: Callable[[MessageResult], None] | None = None
        self.on_unexpected: Callable[[str, bytes, float], None] | None = None
        self.server_error: Ack | None = None
        """The last error ack without an ID (``00000000``) since :meth:`reset`: a server refusing us says why."""
        self._ids = IdAllocator(id_start)
        self._issued = 0  # IDs taken from self._ids so far (see register)
        self._reader = AckReader(max_line=max_line)
        self._pending: dict[str, Submission] = {}
        # IDs given up by their waiter (cancel/timeout), to count their late acks; dict as an ordered set.
        self._abandoned: dict[str, None] = {}
        self._batch = 0

    # ------------------------------------------------------------------------------------------- state
    @property
    def pending_ids(self) -> tuple[str, ...]:
        """IDs registered and not yet acked (nor given up), in send order."""
        return tuple(self._pending)

    @property
    def abandoned_ids(self) -> tuple[str, ...]:
        """IDs given up by their waiter whose late ack has not come (the most recent 4096)."""
        return tuple(self._abandoned)

    def __len__(self) -> int:
        return len(self._pending)

    def partial_line(self) -> bytes:
        """The bytes received after the last complete line (a peer that speaks no line protocol)."""
        return self._reader.framer.partial

    def reset(self) -> None:
        """A new connection: forget a partial line and the last server error (pending calls were failed)."""
        self._reader.reset()
        self.server_error = None

    def come_round(self, next_id: int) -> None:
        """Make ``next_id`` the next ID issued, as if the counter had come round through all 2**32 - 1 IDs (so
        IDs are checked against pending and given-up ones from then on). For tests of the wrap-around."""
        self._ids = IdAllocator(next_id)
        self._issued += 0xFFFFFFFF

    # ------------------------------------------------------------------------------------------- events in
    def register(self, calls: Sequence[SkillCall], new_future: Callable[[], Any] | None = None
                 ) -> tuple[Submission, bytes]:
        """Allocate IDs for ``calls`` and register them as pending; return the submission and the bytes to write.

        Write them at once (an ack can never beat its entry: it is registered first); if the write fails, call
        :meth:`unregister`. ``new_future``: make a future per message (``submit``).
        """
        n = len(calls)
        pending = self._pending
        # An ID is never one still pending or given up (its late ack may still come). The counter cycles through
        # the 2**32 - 1 IDs other than 00000000, so the first 2**32 - 1 IDs it issues are all distinct: only after
        # that (_issued counts them) can an ID repeat, and only then are IDs checked (the check on every send
        # costs ~0.1-0.25 us per message).
        issued = self._issued = self._issued + n
        if n == 1:
            # IdAllocator.next() inline (a round trip's send; a call costs more than the work): the next ID unless
            # it is 00000000 or the last before the wrap, which next() handles.
            allocator = self._ids
            k = allocator._next
            if 0 < k < 0xFFFFFFFF:
                allocator._next = k + 1
                mid = "%08x" % k
            else:
                mid = allocator.next()
            if issued > 0xFFFFFFFF and (mid in pending or mid in self._abandoned):
                mid = self._unused_ids(1)[0]
            ids: tuple[str, ...] = (mid,)
            data = f"{mid}:{calls[0].wire}\r\n".encode("ascii")
        else:
            ids = tuple(self._ids.take(n))
            if issued > 0xFFFFFFFF and (not pending.keys().isdisjoint(ids)
                                        or not self._abandoned.keys().isdisjoint(ids)):
                ids = self._unused_ids(n)
            data = "".join([f"{mid}:{call.wire}\r\n" for mid, call in zip(ids, calls, strict=True)]).encode("ascii")
        batch = self._batch = self._batch + 1
        # Submission(ids, calls, batch), inline for the same reason.
        sub = _new_submission(Submission)
        sub._registry = self
        sub.ids = ids
        sub.calls = calls
        sub.batch = batch
        sub.results = [None] * n
        sub.remaining = n
        if new_future is not None:
            sub.futures = tuple(new_future() for _ in range(n))
        if n == 1:
            pending[ids[0]] = sub
        else:
            pending.update(dict.fromkeys(ids, sub))
        return sub, data

    def unregister(self, sub: Submission) -> None:
        """The write of ``sub`` failed: forget its messages (they were never sent, so no late ack can come)."""
        for mid in sub.ids:
            self._pending.pop(mid, None)
        sub._settled = True

    def _unused_ids(self, n: int) -> tuple[str, ...]:
        """The next ``n`` IDs that are neither pending nor given up (the slow path of :meth:`register`)."""
        out: dict[str, None] = {}
        pending, abandoned, allocator = self._pending, self._abandoned, self._ids
        while len(out) < n:
            mid = allocator.next()
            self._issued += 1
            if mid not in pending and mid not in abandoned:
                out[mid] = None
        return tuple(out)

    def receive(self, data: bytes, t_recv: float) -> None:
        """Route every ack in ``data`` (read at client time ``t_recv``) to its submission. The client's hot path."""
        pending_pop = self._pending.pop
        result_twin = _RESULT_TWIN
        result_cls = MessageResult
        ack_cls = _ACK
        notify = self.on_result
        cur = None  # the submission of the previous ack, and its fields: consecutive acks mostly share one
        calls: Sequence[SkillCall] = ()
        results: list[MessageResult | None] = []
        futs = None
        ids: tuple[str, ...] = ()
        batch = 0
        j = 0
        t_send = 0.0
        routed = 0
        count = 0  # acks of `cur` not yet subtracted from cur.remaining (one update per run of a batch)
        acks = self._reader.feed(data)
        try:
            for ack in acks:
                if type(ack) is not ack_cls:
                    if type(ack) is _BAD:
                        self._unexpected("bad_line", ack.line, t_recv)  # type: ignore[union-attr]
                    else:
                        self._unexpected("oversize", ack.head, t_recv)  # type: ignore[union-attr]
                    continue
                mid = ack.id  # type: ignore[union-attr]
                sub = pending_pop(mid, None)
                if sub is None:
                    self._unmatched(ack, acks, t_recv)  # type: ignore[arg-type]
                    continue
                if sub is not cur:
                    if count:
                        _settle(cur, count)  # type: ignore[arg-type]
                        routed += count
                        count = 0
                    if cur is not None:
                        cur._next_i = j
                    cur = sub
                    calls, results, futs, ids = sub.calls, sub.results, sub.futures, sub.ids
                    batch, t_send, j = sub.batch, sub.t_send_s, sub._next_i
                # Its index: one after the previous ack's (acks come in order), else search.
                i = j if j < len(ids) and ids[j] == mid else ids.index(mid)
                j = i + 1
                call = calls[i]
                if result_twin is not None:  # _make_result(...) inline: a call costs more than the object
                    result = result_twin()
                    result.id = mid
                    result.skill = call.skill
                    result.args = call.args
                    result.batch = batch
                    result.t_send_s = t_send
                    result.t_recv_s = t_recv
                    result.ack = ack
                    result.__class__ = result_cls
                else:
                    result = _make_result(mid, call.skill, call.args, batch, t_send, t_recv, ack)
                results[i] = result
                count += 1
                if ack.status is not _DONE and (sub._first_bad < 0 or i < sub._first_bad):  # type: ignore
                    sub._first_bad = i
                if futs is not None and not futs[i].done():
                    futs[i].set_result(result)
                if notify is not None:
                    notify(result)
        finally:
            if cur is not None:
                cur._next_i = j
                if count:
                    _settle(cur, count)
            self.stats.acks += routed + count

    def _unmatched(self, ack: Ack, acks: list, t_recv: float) -> None:
        # The bytes as received, for the record (the reader keeps them index for index; a rare path).
        line = self._reader.last_lines[next(k for k, a in enumerate(acks) if a is ack)]
        if ack.id in self._abandoned:
            del self._abandoned[ack.id]
            self.stats.late_acks += 1
        elif ack.id == NO_ID:
            # Kept for the loss that usually follows: a server refusing us (too many clients, address not
            # allowed) sends one such ack and closes, and the user should read why, not just "closed by peer".
            self.server_error = ack
            self._unexpected("unroutable_error", line, t_recv)  # type: ignore[arg-type]
        else:
            self._unexpected("unknown_ack", line, t_recv)  # type: ignore[arg-type]

    def _unexpected(self, kind: str, line: bytes, t_recv: float) -> None:
        stats = self.stats
        if kind == "unknown_ack":
            stats.unknown_acks += 1
        elif kind == "unroutable_error":
            stats.unroutable_errors += 1
        else:
            stats.bad_lines += 1
        stats.unexpected.append((t_recv, kind, bytes(line)))
        if self.on_unexpected is not None:
            self.on_unexpected(kind, line, t_recv)

    def release(self, sub: Submission) -> bool:
        """The waiter of ``sub`` is done with it (the ``finally`` of every wait; idempotent): remove its unacked
        messages from the registry and remember them as given up, so their late acks are told from unknown ones.
        Returns False if it was already released."""
        if sub._settled:
            return False
        sub._settled = True
        if sub.remaining and sub._lost_reason is None:
            pending = self._pending
            abandoned = self._abandoned
            for mid, r in zip(sub.ids, sub.results, strict=True):
                if r is None and pending.pop(mid, None) is not None:
                    abandoned[mid] = None
                    if len(abandoned) > _ABANDONED_MEMORY:
                        del abandoned[next(iter(abandoned))]
        return True

    def fail_all(self, why: str) -> list[Submission]:
        """The connection is gone: empty the registry; every pending submission is marked lost (``why``), its
        per-message futures fail with :class:`ConnectionLost` (``unresolved``: that message) and its waiter wakes.
        Returns the submissions, in send order. A waiter then raises ConnectionLost with the batch's ``acked``
        (known done) and ``unresolved`` (may or may not have run) IDs."""
        return fail_taken(self.take_all(), why)

    def take_all(self) -> dict[str, Submission]:
        """Empty the registry at once and return what was pending (message ID -> submission), for
        :func:`fail_taken`: failing tens of thousands of futures takes a while, which a stop need not wait for."""
        pending, self._pending = self._pending, {}
        return pending


def fail_taken(pending: dict[str, Submission], why: str) -> list[Submission]:
    """Fail what :meth:`PendingCalls.take_all` took, as :meth:`PendingCalls.fail_all` says."""
    subs = list({id(sub): sub for sub in pending.values()}.values())  # in send order
    for sub in subs:
        if sub.futures is not None:
            for mid, fut in zip(sub.ids, sub.futures, strict=True):
                if mid in pending and not fut.done():
                    # Per message; wait() merges them into one error with the whole batch's sets.
                    fut.set_exception(lost(why, unresolved=(mid,)))
    for sub in subs:
        sub._lost_reason = why
        if sub._waiter is not None and not sub._waiter.done():
            sub._waiter.set_result(W_LOST)
    return subs


def _settle(sub: Submission, count: int) -> None:
    """``count`` more acks of ``sub`` are in; wake its waiter when that was the last."""
    sub.remaining -= count
    if not sub.remaining and sub._waiter is not None and not sub._waiter.done():
        sub._waiter.set_result(W_ACKED)


def lost(reason: str, *, acked: tuple[str, ...] = (), unresolved: tuple[str, ...] = ()) -> ConnectionLost:
    """A ConnectionLost that remembers ``reason`` without the ID lists, to be re-raised with merged lists."""
    exc = ConnectionLost(reason, acked=acked, unresolved=unresolved)
    exc.reason = reason  # type: ignore[attr-defined]
    return exc


def check_timeout(name: str, value: object, *, none_ok: bool = True) -> float | None:
    """``value`` as seconds: ``None`` (if ``none_ok``) or a finite real > 0; else ValueError naming ``name``."""
    if value is None:
        if none_ok:
            return None
        raise ValueError(f"{name}: a number of seconds is required, not None")
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name}: {value!r} is not a number of seconds")
    seconds = float(value)
    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"{name}: {value!r} is not a finite number of seconds > 0")
    return seconds


def calls_of(commands: Iterable[Any]) -> tuple[SkillCall, ...]:
    """The skill calls of ``commands`` (Commands or SkillCalls), in order; TypeError / ValueError otherwise."""
    from aioadept.commands import Command
    out: list[SkillCall] = []
    for i, c in enumerate(commands):
        if isinstance(c, Command):
            out.extend(c.calls())
        elif isinstance(c, SkillCall):
            out.append(c)
        else:
            raise TypeError(f"commands[{i}]: {c!r} is not a Command")
    if not out:
        raise ValueError("commands: nothing to send")
    return out  # type: ignore[return-value]

