"""Command messages and acknowledgements: values, encoders and parsers for both directions.

Client → server (one command message)::

    ID:SKILL[:ARG,ARG,...]\\r\\n        e.g. eae86869:move_to:-80.000,-481.000,112.500,180.000,90.000,180.000

Server → client (one ack per command message)::

    ID:STATUS:T_START,T_DONE:X,Y,Z,YAW,PITCH,ROLL[:EXTRA...]\\r\\n

``STATUS`` is ``done`` (the original protocol), or our extensions ``error`` (``EXTRA`` = ``CODE:MESSAGE``) and
``aborted`` (flushed by a stop). The original client reads only the first four ``:`` fields, so extensions travel
as trailing fields. See ``docs/protocol.md`` for the grammar. Nothing here does I/O or reads a clock.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any
from enum import Enum

from aioadept.geometry import Pose
from aioadept.protocol.codes import DEFAULT_TEXT, ErrorCode
from aioadept.errors import LocalProtocolError, RemoteProtocolError
from aioadept.protocol.framing import DELIMITER, MAX_LINE

ID_LENGTH = 8
NO_ID = "00000000"
"""ID of an error ack for a line whose own ID could not be recovered; clients never allocate it."""
MAX_SKILL_NAME = 15
"""V+ program names are at most 15 characters."""
MAX_ERROR_TEXT = 80

# Extension skills (docs/protocol.md, "Extensions"). The original V+ server halts on any of them ("undefined
# program"), so a client sends them only to servers that implement the extensions.
STOP_SKILL = "stop"
"""Served the moment it is read: abort the motion in progress, ack everything not yet done ``aborted``, then ack
the stop itself ``done``."""
HERE_SKILL = "here"
"""No motion; the ``done`` ack carries the current pose."""
HELLO_SKILL = "hello"
"""No motion; the ``done`` ack carries two trailing fields: the protocol version and the server's name."""
PROTOCOL_VERSION = 1
"""Version of the extended protocol described in docs/protocol.md (sent in the ``hello`` ack)."""

MAX_NUMBER_CHARS = 24
"""Longest argument text the server accepts (sign, 15 digits, point, decimals): a %.3f real of any magnitude a
robot can use fits; 100-digit numbers (1e99 written out) are refused as text, before any arithmetic."""

_ID_RE = re.compile(r"[0-9A-Za-z]{8}\Z")
_SKILL_RE = re.compile(r"[a-z][a-z0-9._]{0,14}\Z")
_NUMBER_RE = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)\Z")
_INT_RE = re.compile(r"[+-]?\d+\Z")


class Status(str, Enum):
    """Ack status. ``DONE`` is the original protocol's only status; the others are our extensions."""

    DONE = "done"
    ERROR = "error"
    ABORTED = "aborted"


_STATUS_BY_WIRE = {s.value: s for s in Status}
# Enum member lookups (Status.DONE) and .value cost ~0.3 us each in 3.11; the per-message paths use these.
_DONE, _ERROR = Status.DONE, Status.ERROR
_WIRE_BY_STATUS = {s: s.value for s in Status}


def format_arg(value: int | float) -> str:
    """One argument as the original client writes it: ``%.3f`` for reals, ``%d`` for ints (set_speed)."""
    if isinstance(value, bool):
        raise LocalProtocolError("argument: bool is not a number")
    if isinstance(value, int):
        return "%d" % value
    return "%.3f" % value


def check_skill_name(skill: str) -> None:
    """Raise ``ValueError`` unless ``skill`` is a name V+ can CALLS: lowercase, starts with a letter, ≤ 15 chars."""
    if not isinstance(skill, str) or not _SKILL_RE.match(skill):
        raise ValueError(
            f"skill: {skill!r} is not a V+ program name (a letter, then letters, digits, '.' or '_', "
            f"at most {MAX_SKILL_NAME} characters, lowercase)"
        )


def _plain_number(i: int, a: object) -> int | float:
    # numpy scalars and other Real/Integral types become plain int/float, so the wire text is the same for all.
    if isinstance(a, bool) or not isinstance(a, numbers.Real):
        raise ValueError(f"args[{i}]: {a!r} is not a number")
    return int(a) if isinstance(a, numbers.Integral) else float(a)


@dataclass(frozen=True, slots=True)
class SkillCall:
    """A skill name and its numeric arguments: one command message without its ID.

    Validated at construction: a name V+ can call and finite numbers. ``wire`` is the ``SKILL[:ARGS]`` text,
    computed once, so allocating an ID is the only per-send work.
    """

    skill: str
    args: tuple[int | float, ...] = ()
    wire: str = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        check_skill_name(self.skill)
        args = tuple(self.args)
        if not all(type(a) is float or type(a) is int for a in args):
            args = tuple(_plain_number(i, a) for i, a in enumerate(args))
        for i, a in enumerate(args):
            if type(a) is float and not math.isfinite(a):
                raise ValueError(f"args[{i}]: {a!r} is not finite")
        object.__setattr__(self, "args", args)
        wire = self.skill + (":" + ",".join(map(format_arg, args)) if args else "")
        if ID_LENGTH + 1 + len(wire) > MAX_LINE:
            raise ValueError(f"args: the message would be {ID_LENGTH + 1 + len(wire)} characters, over {MAX_LINE}")
        object.__setattr__(self, "wire", wire)


@dataclass(frozen=True, slots=True)
class CommandMessage:
    """A command message as the server sees it: ID, skill name and parsed arguments."""

    id: str
    skill: str
    args: tuple[int | float, ...] = ()


def encode_command(id: str, call: SkillCall) -> bytes:
    """``ID:SKILL[:ARGS]\\r\\n``. The caller owns ID uniqueness (see :class:`IdAllocator`).

    Raises :class:`LocalProtocolError` for an ID that is not 8 letters/digits.
    """
    if not _ID_RE.match(id):
        raise LocalProtocolError(f"id: {id!r} is not 8 letters or digits")
    return f"{id}:{call.wire}\r\n".encode("ascii")


def parse_command(line: bytes) -> CommandMessage:
    """Parse one command line (without delimiter), server side.

    Raises :class:`RemoteProtocolError` with a code from :mod:`codes`; its ``id`` is set when the line starts with
    a valid ID, so the error ack can be routed to the command that caused it.
    """
    if len(line) > MAX_LINE:
        raise RemoteProtocolError(ErrorCode.LINE_TOO_LONG, DEFAULT_TEXT[ErrorCode.LINE_TOO_LONG],
                                  id=recover_id(line), line=line)
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError:
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "non-ASCII bytes", id=recover_id(line),
                                  line=line) from None
    parts = text.split(":")
    mid = parts[0]
    if not _ID_RE.match(mid):
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "bad message ID", line=line)
    if mid == NO_ID:
        # The ID of the server's own refusals and unroutable errors: a command carrying it could not be told apart.
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "reserved message ID 00000000", line=line)
    if len(parts) < 2 or len(parts) > 3:
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "expected ID:SKILL[:ARGS]", id=mid, line=line)
    skill = parts[1]
    if not _SKILL_RE.match(skill):
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "bad skill name", id=mid, line=line)
    args: tuple[int | float, ...] = ()
    if len(parts) == 3:
        tokens = parts[2].split(",")
        vals: list[int | float] = []
        for tok in tokens:
            # No stripping: the grammar is %d / %.3f text, so a space, tab or control character is an error, as
            # are exponents, '_', 'inf' and 'nan' (all of which Python's float() would take).
            if _INT_RE.match(tok):
                vals.append(int(tok))
            elif _NUMBER_RE.match(tok):
                vals.append(float(tok))
            else:
                raise RemoteProtocolError(ErrorCode.ILLEGAL_VALUE, f"not a number: {tok[:16]!r}", id=mid, line=line)
            if len(tok) > MAX_NUMBER_CHARS:
                raise RemoteProtocolError(ErrorCode.ILLEGAL_VALUE, f"number longer than {MAX_NUMBER_CHARS} characters",
                                          id=mid, line=line)
        args = tuple(vals)
    return CommandMessage(mid, skill, args)


def recover_id(line: bytes) -> str | None:
    """The ID at the start of a (possibly broken) line, or None."""
    head = line[: ID_LENGTH + 1]
    if len(head) == ID_LENGTH + 1 and head[ID_LENGTH:] == b":":
        try:
            mid = head[:ID_LENGTH].decode("ascii")
        except UnicodeDecodeError:
            return None
        if _ID_RE.match(mid):
            return mid
    return None


@dataclass(frozen=True, slots=True)
class Ack:
    """One acknowledgement.

    ``t_start_s``/``t_done_s`` are server-clock seconds (since server start, 1 ms resolution); ``pose`` is the
    robot's location (HERE) when the ack was written; ``extra`` holds trailing fields after the pose.
    """

    id: str
    status: Status
    t_start_s: float
    t_done_s: float
    pose: Pose
    extra: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.status is _DONE

    @property
    def error_code(self) -> int | None:
        """The code of an ``error`` ack (None otherwise)."""
        if self.status is not _ERROR or not self.extra:
            return None
        try:
            return int(self.extra[0])
        except ValueError:
            return None

    @property
    def error_message(self) -> str | None:
        """The short text of an ``error`` ack (None otherwise)."""
        if self.status is not _ERROR:
            return None
        return self.extra[1] if len(self.extra) > 1 else ""

    @classmethod
    def error(cls, id: str | None, code: int, message: str | None, t_start_s: float, t_done_s: float,
              pose: Pose) -> Ack:
        """An ``error`` ack; ``message`` defaults to the table's text and is made wire-safe."""
        if message is None:
            try:
                message = DEFAULT_TEXT[ErrorCode(code)]
            except ValueError:
                message = ""
        return cls(id or NO_ID, Status.ERROR, t_start_s, t_done_s, pose, (str(int(code)), sanitize_text(message)))


def sanitize_text(text: str) -> str:
    """Make free text safe as one trailing field: ASCII, no ':' or line breaks, at most 80 characters."""
    clean = text.encode("ascii", "replace").decode("ascii")
    clean = clean.replace(":", ";").replace("\r", " ").replace("\n", " ")
    return clean[:MAX_ERROR_TEXT]


def encode_ack(ack: Ack) -> bytes:
    """``ID:STATUS:T_START,T_DONE:X,Y,Z,YAW,PITCH,ROLL[:EXTRA...]\\r\\n`` with ``%.3f`` numbers."""
    p = ack.pose
    nums = (ack.t_start_s, ack.t_done_s, p.x, p.y, p.z, p.yaw, p.pitch, p.roll)
    if not _ID_RE.match(ack.id):
        raise LocalProtocolError(f"id: {ack.id!r} is not 8 letters or digits")
    if not all(map(math.isfinite, nums)):
        raise LocalProtocolError(f"ack {ack.id}: times and pose must be finite numbers")
    wire_status = _WIRE_BY_STATUS.get(ack.status)
    if wire_status is None:
        raise LocalProtocolError(f"ack {ack.id}: status {ack.status!r} is not one of {list(_WIRE_BY_STATUS.values())}")
    head = "%s:%s:%.3f,%.3f:%.3f,%.3f,%.3f,%.3f,%.3f,%.3f" % (ack.id, wire_status, *nums)
    for f in ack.extra:
        if ":" in f or "\r" in f or "\n" in f or not f.isascii():
            raise LocalProtocolError(f"extra field {f!r} contains ':', a line break or non-ASCII")
    if ack.status is _ERROR and not (ack.extra and _INT_RE.match(ack.extra[0])):
        raise LocalProtocolError(f"ack {ack.id}: an error ack needs an integer code as its first extra field")
    if ack.extra:
        head += ":" + ":".join(ack.extra)
    return head.encode("ascii") + DELIMITER


def parse_ack(line: bytes) -> Ack:
    """Parse one ack line (without delimiter), client side. Raises :class:`RemoteProtocolError`.

    This is the client's hot path (one call per ack), so it avoids regexes and per-field checks where one
    check over all values gives the same answer.
    """
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError:
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "non-ASCII ack", id=recover_id(line),
                                  line=line) from None
    parts = text.split(":")
    if len(parts) < 4:
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "ack has fewer than 4 fields",
                                  id=recover_id(line), line=line)
    mid = parts[0]
    status = _STATUS_BY_WIRE.get(parts[1])
    # str.isalnum() on an ASCII-decoded string is exactly [0-9A-Za-z], as _ID_RE.
    if status is None or len(mid) != ID_LENGTH or not mid.isalnum():
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, f"bad ack head {text[:24]!r}",
                                  id=recover_id(line), line=line)
    times = parts[2].split(",")
    pose_vals = parts[3].split(",")
    try:
        if len(times) != 2 or len(pose_vals) != 6:
            raise ValueError
        t_start = float(times[0])
        t_done = float(times[1])
        x, y, z, yaw, pitch, roll = map(float, pose_vals)
    except ValueError:
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "bad ack times or pose", id=mid,
                                  line=line) from None
    # One sum is finite iff every term is (barring overflow of absurd values, re-checked one by one).
    if not math.isfinite(t_start + t_done + x + y + z + yaw + pitch + roll) and not all(
            map(math.isfinite, (t_start, t_done, x, y, z, yaw, pitch, roll))):
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "non-finite number in ack", id=mid, line=line)
    if len(parts) > 4:
        extra = tuple(parts[4:])
        if status is _ERROR and not _INT_RE.match(extra[0]):
            raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "error ack without a code", id=mid, line=line)
    elif status is _ERROR:
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "error ack without a code", id=mid, line=line)
    else:
        extra = ()
    return _make_ack(mid, status, t_start, t_done, _make_pose(x, y, z, yaw, pitch, roll), extra)


def fast_constructor(cls: type, names: tuple[str, ...]) -> Callable[..., Any]:
    """A positional constructor for a frozen, slotted dataclass that builds the same object in about a third of
    the time of its ``__init__``.

    A frozen dataclass's ``__init__`` goes through ``object.__setattr__`` per field, which is most of the cost of
    parsing an ack. This fills an instance of a plain twin class with the same slots (plain attribute stores,
    which CPython specialises for slots) and then sets its ``__class__`` to ``cls``: the result *is* a ``cls``
    (``type(x) is cls``, same equality, hash, repr and pickling). If the twin's layout is not accepted (a change to
    the class), it sets the slot descriptors directly instead; if the class is not exactly that shape (fields
    ``names``, slots, no ``__post_init__``), it returns the class itself, so it can never produce half-built
    objects.
    """
    try:
        ok = (tuple(f.name for f in dataclasses.fields(cls)) == names and cls.__dict__.get("__slots__") == names
              and not hasattr(cls, "__post_init__"))
    except TypeError:
        ok = False
    if not ok:
        return cls
    twin = type(f"_{cls.__name__}Twin", (), {"__slots__": names})
    env: dict[str, Any] = {"_new": object.__new__, "_cls": cls, "_twin": twin}
    try:
        probe = twin()
        probe.__class__ = cls  # TypeError unless the layouts are the same
        body = ["def make(" + ", ".join(names) + "):", "    o = _twin()"]
        body += [f"    o.{name} = {name}" for name in names]
        body += ["    o.__class__ = _cls", "    return o"]
    except TypeError:
        body = ["def make(" + ", ".join(names) + "):", "    o = _new(_cls)"]
        for i, name in enumerate(names):
            env[f"_s{i}"] = cls.__dict__[name].__set__
            body.append(f"    _s{i}(o, {name})")
        body.append("    return o")
    exec("\n".join(body), env)  # noqa: S102 - generated from field names checked above, as dataclasses does
    make = env["make"]
    # For callers that build inline (the client's per-ack loop): the twin class, or None when not in use.
    make.twin = twin if "_twin" in make.__code__.co_names else None
    return make  # type: ignore[no-any-return]


_make_pose = fast_constructor(Pose, ("x", "y", "z", "yaw", "pitch", "roll"))
_make_ack = fast_constructor(Ack, ("id", "status", "t_start_s", "t_done_s", "pose", "extra"))


class IdAllocator:
    """Message IDs unique per connection: 8 lowercase hex characters, like ``uuid4().hex[:8]``.

    A counter from a random start (passed in, so this stays free of I/O) guarantees that no two of the next
    2**32 - 1 IDs repeat, which a truly random ID does not; ``00000000`` (:data:`NO_ID`) is never issued.
    """

    __slots__ = ("_next", "_run_hi", "_run")

    def __init__(self, start: int) -> None:
        self._next = start & 0xFFFFFFFF
        self._run_hi = -1  # the first 6 digits (n >> 8) of the IDs in _run; -1: none yet
        self._run: list[str] = []

    def next(self) -> str:
        n = self._next
        if n == 0:
            n = 1
        self._next = (n + 1) & 0xFFFFFFFF
        return "%08x" % n

    def take(self, count: int) -> list[str]:
        """The next ``count`` IDs at once (what a batch needs), same sequence as ``count`` calls of :meth:`next`."""
        n = self._next
        end = n + count
        if n == 0 or end > 0x100000000:  # 00000000 is skipped: one at a time
            return [self.next() for _ in range(count)]
        self._next = end & 0xFFFFFFFF
        # IDs in a run of 256 share their first 6 digits: all 256 IDs of the current run are formatted once, and a
        # batch is a slice of that list (a batch of 10 costs one slice instead of a formatting loop: ~0.1 us, not ~1 us,
        # on the client's per-batch path; the run's 256 strings cost ~0.03 us per ID, once).
        lo = n & 0xFF
        if lo + count <= 256:
            if n >> 8 != self._run_hi:
                self._new_run(n >> 8)
            return self._run[lo:lo + count]
        out: list[str] = []
        while n < end:
            stop = min((n | 0xFF) + 1, end)
            if n >> 8 != self._run_hi:
                self._new_run(n >> 8)
            out += self._run[n & 0xFF:((stop - 1) & 0xFF) + 1]
            n = stop
        return out

    def _new_run(self, hi: int) -> None:
        prefix = "%06x" % hi
        self._run_hi = hi
        self._run = [prefix + h for h in _HEX2]


_HEX2 = tuple("%02x" % k for k in range(256))
