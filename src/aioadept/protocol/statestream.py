"""The V+ server's state stream lines (``vplus/rsstate.V2``), sans-IO: one line of text in, a sample out.

A controller has no ZeroMQ, so the V+ server writes its state as text lines on a TCP port of its own and
``aioadept state`` (:mod:`aioadept.cli.state`) turns each into the ``robot.state`` message the simulator publishes.
The format is in docs/protocol.md, section 9::

    S1 t=12.345 j=0.000,-90.000,180.000,0.000,90.000,0.000 p=480.000,0.000,710.000,0.000,180.000,0.000 mv=0 sp=100 er=0 air=0

- the first word is the format tag; ``S1`` is this format. A line with another tag is skipped (a newer server may
  send a second kind of line), never an error;
- then ``key=value`` words separated by spaces. ``t`` (s, the acks' clock), ``j`` (six joint angles, deg) and
  ``p`` (x, y, z, yaw, pitch, roll; mm, deg) are required; ``mv`` (1 while moving), ``sp`` (program speed, %),
  ``er`` (last V+ error code, 0 none) and ``air`` (1 when the vacuum valve is open) are optional;
- a key this reader does not know is kept in :attr:`StateSample.extra` (text), so a server may add fields (digital
  I/O, the hand) without breaking older readers; a known key given twice keeps the last value.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from aioadept.geometry import Pose
from aioadept.protocol.codes import ErrorCode
from aioadept.errors import RemoteProtocolError

STATE_TAG = "S1"
"""The format tag of the lines this module reads and writes."""
MAX_STATE_LINE = 1024
"""Longest state line accepted (bytes, without CR LF): room for fields added later; the shipped task writes ~130."""

_EMPTY: Mapping[str, str] = MappingProxyType({})


@dataclass(frozen=True, slots=True)
class StateSample:
    """One state line: the server clock ``t_s``, the joints, the pose and the status fields."""

    t_s: float
    joints_deg: tuple[float, ...]
    pose: Pose
    moving: bool = False
    speed_pct: float = 100.0
    error_code: int = 0
    air: bool = False
    extra: Mapping[str, str] = field(default_factory=lambda: _EMPTY)
    """Fields of the line this reader does not know (key -> text)."""


def _bad(line: str, why: str) -> RemoteProtocolError:
    return RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, f"state line: {why}", line=line.encode("latin-1"))


def _numbers(line: str, key: str, text: str, n: int) -> tuple[float, ...]:
    parts = text.split(",")
    if len(parts) != n:
        raise _bad(line, f"{key} needs {n} numbers, got {len(parts)}")
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        raise _bad(line, f"{key}: not a number in {text!r}") from None
    if not all(math.isfinite(v) for v in vals):
        raise _bad(line, f"{key}: not finite")
    return vals


def _number(line: str, key: str, text: str) -> float:
    return _numbers(line, key, text, 1)[0]


def parse_state_line(line: bytes | str) -> StateSample | None:
    """Parse one line (without CR LF). None for a line of another format tag (or an empty one); a malformed
    ``S1`` line raises :class:`RemoteProtocolError` (code MALFORMED_MESSAGE)."""
    text = line.decode("latin-1") if isinstance(line, bytes) else line
    words = text.split()
    if not words or words[0] != STATE_TAG:
        return None
    fields: dict[str, str] = {}
    for w in words[1:]:
        key, eq, value = w.partition("=")
        if not eq or not key:
            raise _bad(text, f"{w!r} is not key=value")
        fields[key] = value
    for key in ("t", "j", "p"):
        if key not in fields:
            raise _bad(text, f"no {key}=")
    t = _number(text, "t", fields.pop("t"))
    joints = _numbers(text, "j", fields.pop("j"), 6)
    pose = Pose(*_numbers(text, "p", fields.pop("p"), 6))
    moving = _number(text, "mv", fields.pop("mv")) != 0 if "mv" in fields else False
    speed = _number(text, "sp", fields.pop("sp")) if "sp" in fields else 100.0
    error = int(_number(text, "er", fields.pop("er"))) if "er" in fields else 0
    air = _number(text, "air", fields.pop("air")) != 0 if "air" in fields else False
    return StateSample(t, joints, pose, moving, speed, error, air, MappingProxyType(fields) if fields else _EMPTY)


def encode_state_line(s: StateSample) -> bytes:
    """The line for ``s`` with CR LF, as the V+ task writes it (``%.3f``; status fields as integers)."""
    j = ",".join("%.3f" % v for v in s.joints_deg)
    p = ",".join("%.3f" % v for v in s.pose)
    words = [STATE_TAG, "t=%.3f" % s.t_s, "j=" + j, "p=" + p, "mv=%d" % bool(s.moving),
             "sp=%.0f" % s.speed_pct, "er=%d" % s.error_code, "air=%d" % bool(s.air)]
    words += [f"{k}={v}" for k, v in s.extra.items()]
    return (" ".join(words) + "\r\n").encode("latin-1")


__all__ = ["MAX_STATE_LINE", "STATE_TAG", "StateSample", "encode_state_line", "parse_state_line"]
