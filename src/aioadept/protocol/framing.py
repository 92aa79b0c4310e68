"""Line framing: any split of a byte stream in, the same complete lines out.

TCP delivers bytes, not messages: one read may hold half a line or a thousand lines (V+ READ is not line-framed
either). :class:`LineFramer` buffers and cuts at ``\\n``, dropping one ``\\r`` before it, so ``\\r\\n`` (what both
peers send) and bare ``\\n`` both work. A line longer than ``max_line`` characters is reported once as
:class:`Oversize` and skipped up to the next delimiter, so the stream resynchronises and stays usable.
"""

from __future__ import annotations

from dataclasses import dataclass

MAX_LINE = 128
"""Longest command line (without the delimiter) a V+ string can hold."""

MAX_ACK_LINE = 1024
"""Longest ack line a client accepts. Acks are not bound by the 128-character limit (V+ WRITE concatenates several
strings), and an error ack with its message can exceed 128, so clients frame acks with this larger limit."""

DELIMITER = b"\r\n"


@dataclass(frozen=True, slots=True)
class Oversize:
    """A line exceeded the limit. ``head`` is its first ``max_line`` bytes (enough to recover an ID)."""

    head: bytes


class LineFramer:
    """Buffers bytes and returns complete lines (without delimiter) and :class:`Oversize` events.

    Empty lines are skipped. The result does not depend on how the stream is split into ``feed`` calls.
    """

    __slots__ = ("max_line", "_buf", "_discarding")

    def __init__(self, max_line: int = MAX_LINE) -> None:
        if max_line < 1:
            raise ValueError("max_line: must be >= 1")
        self.max_line = max_line
        self._buf = b""
        # True after an Oversize was reported for the line in progress: drop bytes up to the next "\n".
        self._discarding = False

    @property
    def buffered(self) -> int:
        """Bytes held for an incomplete line."""
        return len(self._buf)

    @property
    def partial(self) -> bytes:
        """The bytes held for an incomplete line (what a peer that never ends a line has sent)."""
        return self._buf

    @property
    def in_line(self) -> bool:
        """True between a line's first byte and its delimiter (also while skipping an oversize line's rest)."""
        return bool(self._buf) or self._discarding

    def feed(self, data: bytes) -> list[bytes | Oversize]:
        """Add ``data``; return the lines and events it completes, in stream order."""
        # Fast paths for what peers actually send: whole CRLF lines, nothing pending. Same result as the general
        # path below (each "\n" is part of a "\r\n", no line empty or too long), with the per-line work in C.
        if not self._buf and not self._discarding:
            max_line = self.max_line
            if data.endswith(b"\r\n"):
                # One line (a round trip's read): its only "\n" is the last byte.
                if data.find(b"\n") == len(data) - 1 and 2 < len(data) <= max_line + 2:
                    return [data[:-2]]
                # Many lines: as many "\r\n" (which cannot overlap) as "\n"; no line is longer than the chunk.
                lines = data.split(b"\r\n")
                if len(lines) - 1 == data.count(b"\n"):
                    lines.pop()
                    if all(lines) and (len(data) - 2 <= max_line or max(map(len, lines)) <= max_line):
                        return lines  # type: ignore[return-value]
        out: list[bytes | Oversize] = []
        if b"\n" not in data:
            if self._discarding:
                return out
            self._buf += data
            self._check_partial(out)
            return out
        parts = (self._buf + data).split(b"\n")
        self._buf = parts.pop()
        if self._discarding:
            del parts[0]  # the tail of a line already reported as Oversize
            self._discarding = False
        max_line = self.max_line
        for line in parts:
            if line.endswith(b"\r"):
                line = line[:-1]
            if not line:
                continue
            if len(line) > max_line:
                out.append(Oversize(line[:max_line]))
            else:
                out.append(line)
        self._check_partial(out)
        return out

    def _check_partial(self, out: list[bytes | Oversize]) -> None:
        # A partial line of max_line + 1 bytes can still be valid if its last byte is the "\r" of "\r\n";
        # anything longer can never be, so report it now instead of buffering without bound.
        if len(self._buf) > self.max_line + 1:
            out.append(Oversize(self._buf[: self.max_line]))
            self._buf = b""
            self._discarding = True

    def reset(self) -> None:
        """Forget any partial line (e.g. after a reconnect)."""
        self._buf = b""
        self._discarding = False
