"""The robot bridge's payloads (sans-IO): what an application's query carries and what the bridge answers.

Where it sits: between :class:`aioadept.bridge.client.BridgeClient` (an application) and
:class:`aioadept.bridge.node.Bridge` (the one writer to the controller), over Zenoh queries on
``aioadept/<cell>/<robot>/cmd`` (docs/bridge.md). No I/O here: bytes in, values out.

Why the paper's wire lines and not a Protobuf: a query is one batch of the robot protocol itself, so the bridge
validates it with the same parser the servers use (:func:`aioadept.protocol.parse_command`), forwards it with the
same client, and a trace of the bridge reads like a trace of the TCP link; a second schema would be a second
grammar to keep in step with the first.

- Query: payload = one or more command lines ``ID:SKILL[:ARGS]\\r\\n`` (the application's own IDs), attachment =
  the application's name. A ``stop`` travels alone.
- Reply ``ok``: the acks of those lines, in order, with the application's IDs (the bridge allocated the
  controller-side IDs and maps them back), same grammar as on TCP.
- Reply ``err``: one line ``KIND:ACKED:UNRESOLVED:TEXT`` (ID lists comma-separated, may be empty), KIND one of
  :data:`ERR_KINDS`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from aioadept.protocol import STOP_SKILL, SkillCall, parse_command
from aioadept.errors import RemoteProtocolError
from aioadept.errors import MalformedRequest

__all__ = ["ERR_KINDS", "MAX_QUEUED_PER_APP", "MAX_QUEUED_TOTAL", "BridgeRequest", "BridgeFailure", "MAX_BATCH", "cmd_key", "app_key", "apps_key",
           "state_key", "bridge_key", "claim_key", "claims_key", "parse_request", "encode_request", "encode_failure",
           "parse_failure"]

MAX_BATCH = 64
"""At most this many command lines in one query (the servers admit 64 queued messages per connection)."""
MAX_QUEUED_PER_APP = 64
"""At most this many batches of one application wait in the bridge; a further query is answered ``busy``."""
MAX_QUEUED_TOTAL = 256
"""At most this many batches of all applications wait in the bridge (and as many queries wait to be read); a
further query is answered ``full``. Bounds the bridge's memory whatever the number of application names."""
ERR_KINDS = ("malformed", "aborted", "dropped", "lost", "timeout", "closed", "busy", "full")
"""``malformed``: the query was refused, nothing sent. ``aborted``: a stop (from ``TEXT``'s application) came
before the batch was sent: never sent. ``dropped``: the application vanished before its batch was sent.
``lost``: the controller link dropped (``ACKED`` known done, ``UNRESOLVED`` may or may not have run).
``timeout``: no ack in time (``UNRESOLVED`` may still run). ``closed``: the bridge is shutting down, not sent.
``busy``: the application already has :data:`MAX_QUEUED_PER_APP` batches waiting in the bridge, not sent.
``full``: the bridge already holds :data:`MAX_QUEUED_TOTAL` batches of all applications, not sent."""

_NAME = re.compile(r"^[A-Za-z0-9_.\-]{1,64}$")
_ROOT = "aioadept"


def _chunk(what: str, value: str) -> str:
    if not isinstance(value, str) or not _NAME.match(value):
        raise ValueError(f"{what} {value!r}: use 1-64 letters, digits, '_', '.', '-'")
    return value


def bridge_key(cell: str, robot: str) -> str:
    """The bridge's liveliness token (a node of the cell, as :class:`~aioadept.bus.presence.NodeWatcher` sees it)."""
    return f"{_ROOT}/{_chunk('cell', cell)}/{_chunk('robot', robot)}"


def cmd_key(cell: str, robot: str) -> str:
    return bridge_key(cell, robot) + "/cmd"


def state_key(cell: str, robot: str) -> str:
    return bridge_key(cell, robot) + "/state"


def apps_key(cell: str, robot: str) -> str:
    """The liveliness keys of the applications of one bridge (wildcard)."""
    return bridge_key(cell, robot) + "/apps/*"


def app_key(cell: str, robot: str, app: str) -> str:
    return bridge_key(cell, robot) + "/apps/" + _chunk("application", app)


SERVING = "serving"
"""The chunk after a claim's key once that bridge serves: ``aioadept/<cell>/<robot>/bridge/<claim>/serving``."""


def claim_key(cell: str, robot: str, claim: str) -> str:
    """A bridge's claim on the robot's name (a liveliness token held for the bridge's life, docs/bridge.md "One
    bridge per name"); ``claim`` sorts by start time (``<ns since the epoch, 20 digits>-<random>``)."""
    return bridge_key(cell, robot) + "/bridge/" + _chunk("claim", claim)


def claims_key(cell: str, robot: str) -> str:
    """Every bridge's claim on the robot's name, and their ``serving`` marks (wildcard)."""
    return bridge_key(cell, robot) + "/bridge/**"


@dataclass(frozen=True, slots=True)
class BridgeRequest:
    """One application's batch: its name, its own message IDs and the skill calls, in order."""

    app: str
    ids: tuple[str, ...]
    calls: tuple[SkillCall, ...]

    @property
    def is_stop(self) -> bool:
        return self.calls[0].skill == STOP_SKILL


def encode_request(ids: tuple[str, ...], calls: tuple[SkillCall, ...]) -> bytes:
    return b"".join(f"{i}:{c.wire}\r\n".encode("ascii") for i, c in zip(ids, calls, strict=True))


def parse_request(payload: bytes, app: bytes | None) -> BridgeRequest:
    """The batch of one query; raises :class:`MalformedRequest` naming what is wrong."""
    if not app:
        raise MalformedRequest("no application name (the query's attachment)")
    try:
        name = _chunk("application", app.decode("ascii"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise MalformedRequest(f"application name {app[:40]!r} is not 1-64 letters, digits, '_', '.', '-'") \
            from exc
    lines = [ln for ln in payload.replace(b"\r", b"").split(b"\n") if ln]
    if not lines:
        raise MalformedRequest("empty query: expected command lines ID:SKILL[:ARGS]")
    if len(lines) > MAX_BATCH:
        raise MalformedRequest(f"{len(lines)} command lines in one query, over {MAX_BATCH}")
    ids: list[str] = []
    calls: list[SkillCall] = []
    for n, line in enumerate(lines, 1):
        try:
            msg = parse_command(line)
            call = SkillCall(msg.skill, msg.args)
        except (RemoteProtocolError, ValueError) as exc:
            raise MalformedRequest(f"line {n} {line[:40]!r}: {exc}") from None
        if msg.id in ids:
            raise MalformedRequest(f"line {n}: ID {msg.id} used twice in one query")
        ids.append(msg.id)
        calls.append(call)
    if len(calls) > 1 and any(c.skill == STOP_SKILL for c in calls):
        raise MalformedRequest("a stop travels alone in its query")
    return BridgeRequest(name, tuple(ids), tuple(calls))


@dataclass(frozen=True, slots=True)
class BridgeFailure:
    """An ``err`` reply: ``kind`` (one of :data:`ERR_KINDS`), the IDs known done and those of unknown fate."""

    kind: str
    text: str
    acked: tuple[str, ...] = ()
    unresolved: tuple[str, ...] = ()


def encode_failure(f: BridgeFailure) -> bytes:
    if f.kind not in ERR_KINDS:
        raise ValueError(f"kind {f.kind!r} is not one of {ERR_KINDS}")
    text = " ".join(f.text.split())
    return f"{f.kind}:{','.join(f.acked)}:{','.join(f.unresolved)}:{text}".encode("utf-8", "replace")


def parse_failure(payload: bytes) -> BridgeFailure:
    """An ``err`` reply's payload; one that does not parse becomes kind ``malformed`` with the raw text."""
    text = payload.decode("utf-8", "replace")
    parts = text.split(":", 3)
    if len(parts) == 4 and parts[0] in ERR_KINDS:
        return BridgeFailure(parts[0], parts[3], tuple(filter(None, parts[1].split(","))),
                             tuple(filter(None, parts[2].split(","))))
    return BridgeFailure("malformed", text)
