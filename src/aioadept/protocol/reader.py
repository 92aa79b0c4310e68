"""AckReader: the one reader of ack streams, bytes in, values out (client side of the data path).

Every place that reads acks uses it: :class:`aioadept.client.PendingCalls` (the client's registry), the test
doubles and the tests that talk to a server over raw sockets. It is :class:`~aioadept.protocol.LineFramer` plus
:func:`~aioadept.protocol.parse_ack`, with the same results and errors, made fast for the stream a robot server
writes::

    reader = AckReader()
    for item in reader.feed(chunk):       # Ack, or BadAck / Oversize for a line that is not one
        ...
    acks = reader.acks(chunk)              # strict: the acks, RemoteProtocolError for anything else

Consecutive acks often repeat their pose text (every ack written while the robot stands still) and their times
text (acks written within one millisecond, the server clock's resolution). A plain ``done`` ack whose pose text
is the previous ack's reuses that (immutable) Pose object and, for the same times text, the same floats, without
parsing them again; its values are built by filling a twin class with the same slots (see
:func:`~aioadept.protocol.messages.fast_constructor`). Anything else takes :func:`parse_ack`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from aioadept.geometry import Pose
from aioadept.protocol.codes import ErrorCode
from aioadept.errors import RemoteProtocolError
from aioadept.protocol.framing import MAX_ACK_LINE, LineFramer, Oversize
from aioadept.protocol.messages import ID_LENGTH, Ack, Status, _make_ack, parse_ack

__all__ = ["AckReader", "BadAck"]

_DONE = Status.DONE
# The twin class behind _make_ack, for feed()'s inline build (a call per ack costs more than the object).
_ACK_TWIN = getattr(_make_ack, "twin", None)


@dataclass(frozen=True, slots=True)
class BadAck:
    """A complete line from the peer that is not an ack; ``error`` says why (its ``id`` when recoverable)."""

    line: bytes
    error: RemoteProtocolError


class AckReader:
    """Cuts a byte stream into acks: :meth:`feed` bytes, get :class:`Ack`, :class:`BadAck` and
    :class:`~aioadept.protocol.Oversize` values in stream order, whatever the split of the stream."""

    __slots__ = ("_framer", "_pose_text", "_pose", "_times_text", "_times", "_tail", "last_lines")

    def __init__(self, max_line: int = MAX_ACK_LINE) -> None:
        self._framer = LineFramer(max_line=max_line)
        self._pose_text: bytes | None = None  # None until a pose has been parsed: never equal to a field
        self._pose: Pose | None = None
        self._times_text: bytes | None = None
        self._times = (0.0, 0.0)
        # Everything after the ID of the last plain `done` ack taken by feed()'s fast path (":done:TIMES:POSE"),
        # whose times and pose are _times and _pose; None when they may not match (after parse()).
        self._tail: bytes | None = None
        self.last_lines: list[bytes | Oversize] = []
        """The lines behind the values of the last :meth:`feed`, index for index (the bytes as received)."""

    @property
    def framer(self) -> LineFramer:
        """The line framer underneath (``buffered``, ``in_line``)."""
        return self._framer

    def reset(self) -> None:
        """Forget a partial line (a new connection)."""
        self._framer.reset()

    def parse(self, line: bytes) -> Ack:
        """One complete line (without delimiter) -> Ack, exactly as :func:`parse_ack`, remembering the pose and
        times text for the next. Raises :class:`RemoteProtocolError`."""
        self._tail = None
        parts = line.split(b":")
        if len(parts) != 4 or parts[3] != self._pose_text or parts[1] != b"done":
            ack = parse_ack(line)
            if len(parts) >= 4:
                self._pose_text = parts[3]
                self._pose = ack.pose
                self._times_text = parts[2]
                self._times = (ack.t_start_s, ack.t_done_s)
            return ack
        # A plain `done` ack with the pose of the previous one: only the head and times are new. bytes.isalnum()
        # is ASCII-only, so this checks the ID exactly as parse_ack does; float() takes ASCII bytes.
        mid = parts[0]
        if len(mid) != ID_LENGTH or not mid.isalnum():
            return parse_ack(line)
        if parts[2] != self._times_text:
            times = parts[2].split(b",")
            if len(times) != 2:
                return parse_ack(line)
            try:
                t_start = float(times[0])
                t_done = float(times[1])
            except ValueError:
                return parse_ack(line)
            if not math.isfinite(t_start + t_done):
                return parse_ack(line)
            self._times_text = parts[2]
            self._times = (t_start, t_done)
        t_start, t_done = self._times
        return _make_ack(mid.decode("ascii"), _DONE, t_start, t_done, self._pose, ())

    def feed(self, data: bytes) -> list[Ack | BadAck | Oversize]:
        """Add ``data``; return the acks (and non-acks) it completes, in stream order. Never raises for what the
        peer sent. The client's hot path: the common line is handled inline, as :meth:`parse` would."""
        out: list[Ack | BadAck | Oversize] = []
        append = out.append
        pose_text, pose = self._pose_text, self._pose
        times_text = self._times_text
        t_start, t_done = self._times
        tail = self._tail
        twin = _ACK_TWIN
        ack_cls = Ack
        isfinite = math.isfinite
        items = self.last_lines = self._framer.feed(data)
        try:
            for item in items:
                if type(item) is not bytes:
                    append(item)
                    continue
                # The same ack as the previous one but for its ID (acks written in one millisecond, the robot at
                # rest): one comparison instead of splitting the line; the ID is checked as parse_ack does.
                if item[ID_LENGTH:] == tail:
                    mid_b = item[:ID_LENGTH]
                    ok = mid_b.isalnum()
                else:
                    ok = False
                    parts = item.split(b":")
                    if len(parts) == 4 and parts[3] == pose_text and parts[1] == b"done":
                        mid_b = parts[0]
                        ok = len(mid_b) == ID_LENGTH and mid_b.isalnum()
                        if ok and parts[2] != times_text:
                            # A wrong number of times is a ValueError like a bad float.
                            try:
                                ts, td = map(float, parts[2].split(b","))
                            except ValueError:
                                ok = False
                            else:
                                if isfinite(ts + td):
                                    times_text, t_start, t_done = parts[2], ts, td
                                else:
                                    ok = False
                        if ok:
                            tail = item[ID_LENGTH:]  # validated: this ack's status, times and pose
                if ok:
                    if twin is not None:  # _make_ack(...) inline
                        ack = twin()
                        ack.id = mid_b.decode("ascii")
                        ack.status = _DONE
                        ack.t_start_s = t_start
                        ack.t_done_s = t_done
                        ack.pose = pose
                        ack.extra = ()
                        ack.__class__ = ack_cls
                    else:
                        ack = _make_ack(mid_b.decode("ascii"), _DONE, t_start, t_done, pose, ())
                    append(ack)
                    continue
                # The general path: sync the remembered texts both ways around parse().
                self._times_text, self._times = times_text, (t_start, t_done)
                try:
                    append(self.parse(item))
                except RemoteProtocolError as exc:
                    append(BadAck(item, exc))
                tail = None  # parse() may have changed the times and pose
                pose_text, pose = self._pose_text, self._pose
                times_text = self._times_text
                t_start, t_done = self._times
        finally:
            if times_text is not self._times_text:  # keep the last times for the next read
                self._times_text, self._times = times_text, (t_start, t_done)
            self._tail = tail
        return out

    def acks(self, data: bytes) -> list[Ack]:
        """:meth:`feed` for peers that must send acks only (tests, tools): RemoteProtocolError on the first line
        that is not one (the lines after it in ``data`` are lost)."""
        out = self.feed(data)
        for item in out:
            if type(item) is BadAck:
                raise item.error
            if type(item) is Oversize:
                raise RemoteProtocolError(ErrorCode.LINE_TOO_LONG, f"ack line over {self._framer.max_line} bytes",
                                          line=item.head)
        return out  # type: ignore[return-value]
