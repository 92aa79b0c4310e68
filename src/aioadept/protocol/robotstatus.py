"""The ``status`` skill's answer, sans-IO: the trailing fields of its ``done`` ack, encoded by the sim and parsed by
the client (the V+ server writes the same text in ``vplus/rsskills.V2``). docs/protocol.md, section 4.7::

    ID:done:T0,T1:X,Y,Z,YAW,PITCH,ROLL:mv=0,sp=100,er=0,pw=1,es=0,hd=o:ERROR TEXT

The first trailing field is ``key=value`` pairs separated by commas, so a server may add keys and an older client
keeps what it does not know in :attr:`RobotStatus.extra`; the second is the text of the last error (empty when
there is none). Short keys, because a V+ ack line is at most 128 characters: ``mv`` moving (1/0), ``sp`` program
speed (%), ``er`` last error code (0: none), ``pw`` high power on (1/0), ``es`` E-stop pressed (1/0), ``hd`` the
hand as its two valve outputs command it (``o`` open, ``c`` closed, ``r`` relaxed: both off, ``x`` both on, a
wiring or program fault), ``ts`` the simulated robot's time scale (its motions run that many times faster than
the program speed says; the Python sim sends it, a real controller runs in real time and leaves it out). A key the
server cannot know is left out and reads as None.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

from aioadept.protocol.codes import ErrorCode
from aioadept.errors import RemoteProtocolError

STATUS_SKILL = "status"

_EMPTY: Mapping[str, str] = MappingProxyType({})


@dataclass(frozen=True, slots=True)
class RobotStatus:
    """What ``status`` reports. ``power``/``estop`` are None when the server did not say."""

    moving: bool
    speed_pct: float
    error_code: int = 0
    error_text: str = ""
    power: bool | None = None
    estop: bool | None = None
    hand: str | None = None
    """``"open"``, ``"closed"``, ``"relaxed"`` or ``"both"`` (both valves on): what the valves command, not where
    the fingers are (they are still travelling for a moment after a switch)."""
    extra: Mapping[str, str] = field(default_factory=lambda: _EMPTY)
    """Keys of the answer this client does not know (key -> text), e.g. the hand's."""
    time_scale: float | None = None
    """A simulated robot's speed-up (> 0; the sim's ``--time-scale``); None from a server that does not say (the V+
    server: a real controller moves in real time)."""


HAND_CODES = {"open": "o", "closed": "c", "relaxed": "r", "both": "x"}
"""``RobotStatus.hand`` -> its ``hd=`` letter."""
_HAND_NAMES = {v: k for k, v in HAND_CODES.items()}


def hand_of_valves(open_on: bool, close_on: bool) -> str:
    """The ``RobotStatus.hand`` word for the two valve outputs' states."""
    return ("both" if close_on else "open") if open_on else ("closed" if close_on else "relaxed")


def encode_status_fields(st: RobotStatus) -> tuple[str, str]:
    """The two trailing fields of the ``status`` ack for ``st`` (the text is the caller's to sanitise)."""
    pairs = [f"mv={int(bool(st.moving))}", "sp=%g" % st.speed_pct, f"er={int(st.error_code)}"]
    if st.power is not None:
        pairs.append(f"pw={int(st.power)}")
    if st.estop is not None:
        pairs.append(f"es={int(st.estop)}")
    if st.hand is not None:
        pairs.append(f"hd={HAND_CODES[st.hand]}")
    if st.time_scale is not None:
        pairs.append("ts=%g" % st.time_scale)
    pairs += [f"{k}={v}" for k, v in st.extra.items()]
    return ",".join(pairs), st.error_text


def _num(key: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, f"status: {key}={text!r} is not a number") from None
    if not math.isfinite(v):
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, f"status: {key} is not finite")
    return v


def parse_status_fields(extra: Sequence[str]) -> RobotStatus:
    """The :class:`RobotStatus` of a ``status`` ack's trailing fields; RemoteProtocolError if they are not one."""
    if not extra:
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "status: the ack has no status fields")
    fields: dict[str, str] = {}
    for pair in extra[0].split(","):
        key, eq, value = pair.strip().partition("=")
        if not eq or not key:
            raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, f"status: {pair!r} is not key=value")
        fields[key] = value
    for key in ("mv", "sp"):
        if key not in fields:
            raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, f"status: no {key}=")
    moving = _num("mv", fields.pop("mv")) != 0
    speed = _num("sp", fields.pop("sp"))
    code = int(_num("er", fields.pop("er"))) if "er" in fields else 0
    power = _num("pw", fields.pop("pw")) != 0 if "pw" in fields else None
    estop = _num("es", fields.pop("es")) != 0 if "es" in fields else None
    hand = None
    if "hd" in fields:
        hand = _HAND_NAMES.get(fields.pop("hd").strip())
        if hand is None:
            raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, "status: hd= is not one of o, c, r, x")
    time_scale = _num("ts", fields.pop("ts")) if "ts" in fields else None
    if time_scale is not None and not time_scale > 0:
        raise RemoteProtocolError(ErrorCode.MALFORMED_MESSAGE, f"status: ts={time_scale:g} is not > 0")
    text = ":".join(extra[1:])
    return RobotStatus(moving, speed, code, text, power, estop, hand,
                       MappingProxyType(fields) if fields else _EMPTY, time_scale)


__all__ = ["HAND_CODES", "STATUS_SKILL", "RobotStatus", "hand_of_valves", "encode_status_fields", "parse_status_fields"]
