"""One bridge per robot name: the claim a :class:`~aioadept.bridge.node.Bridge` holds on ``aioadept/<cell>/<robot>``
over Zenoh liveliness (docs/bridge.md, "One bridge per name").

A bridge declares its claim (a liveliness token whose name sorts by start time), then asks Zenoh for every claim and
node token already on the name and refuses to start (:class:`BridgeNameTaken`) if there is another one. Once it
serves it marks its claim ``serving``; if an earlier bridge's ``serving`` claim turns up later (two Zenoh networks
joined), :class:`NameClaim` tells its owner, which stops serving.
"""

from __future__ import annotations

import asyncio
import logging
import secrets
import time
from collections.abc import Callable
from typing import Any

from aioadept.bridge.wire import SERVING, bridge_key, claim_key, claims_key
from aioadept.errors import BridgeNameTaken

__all__ = ["NameClaim", "new_claim"]

log = logging.getLogger("aioadept.bridge")


def new_claim() -> str:
    """A fresh claim: sorts by start time (ties: by the random part)."""
    return f"{time.time_ns():020d}-{secrets.token_hex(4)}"


class NameClaim:
    """``claim`` on ``aioadept/<cell>/<name>``; ``on_earlier(claim)`` is called (in the loop) when an earlier bridge's
    serving claim turns up after :meth:`serve`. Every Zenoh entity it declares is appended to ``entities`` (the
    owner undeclares them)."""

    def __init__(self, cell: str, name: str, claim: str, entities: list[Any],
                 on_earlier: Callable[[str], None]) -> None:
        self.cell = cell
        self.name = name
        self.claim = claim
        self._entities = entities
        self._on_earlier = on_earlier
        self._base = bridge_key(cell, name)
        self._serving = False
        self._rivals: set[str] = set()  # other claims seen while starting
        self._loop: asyncio.AbstractEventLoop | None = None

    async def take(self, s: Any, zenoh: Any, timeout_s: float) -> None:
        """Declare this bridge's claim, then ask Zenoh for every claim and node token on the name: any other one
        (or one the claims subscriber reports meanwhile) and this bridge refuses (:class:`BridgeNameTaken`). Within
        one router this holds even for two bridges started at the same instant: each declares before it asks, and
        the router handles one session's messages in order, so at least one of the two sees the other's claim (both
        may: then both refuse, and starting again settles it)."""
        self._loop = asyncio.get_running_loop()
        self._entities.append(s.liveliness().declare_token(claim_key(self.cell, self.name, self.claim)))
        self._entities.append(s.liveliness().declare_subscriber(
            claims_key(self.cell, self.name), zenoh.handlers.Callback(self._on_claim_thread), history=True))
        found = await _live_keys(s, self._base + "/**", timeout_s)
        node = self._base in found
        for key in found:
            self._on_claim(key, True)
        if node or self._rivals:
            what = (f"another bridge's claim {sorted(self._rivals)[0]}" if self._rivals
                    else "another node's liveliness token")
            raise BridgeNameTaken(
                f"the robot name {self._base} is taken on this Zenoh network ({what}): a second bridge would run "
                "every command twice; stop the other bridge first or give another --cell/--name (a bridge that just "
                "died frees the name when Zenoh drops its link)")

    def serve(self, s: Any) -> None:
        """Mark the claim ``serving``: from now on an earlier serving claim makes this bridge back off."""
        self._serving = True
        self._entities.append(s.liveliness().declare_token(claim_key(self.cell, self.name, self.claim) + "/" +
                                                           SERVING))

    def _on_claim_thread(self, sample: Any) -> None:
        from aioadept.bus import zenoh as zb

        alive = sample.kind == zb._zenoh().SampleKind.PUT
        loop = self._loop
        if loop is not None:
            _call_soon(loop, self._on_claim, str(sample.key_expr), alive)

    def _on_claim(self, key: str, alive: bool) -> None:
        prefix = self._base + "/bridge/"
        if not alive or not key.startswith(prefix):
            return
        claim, _, mark = key[len(prefix):].partition("/")
        if claim == self.claim:
            return
        if not self._serving:
            self._rivals.add(claim)
        elif mark == SERVING and claim < self.claim:
            self._on_earlier(claim)
        else:  # a later bridge: it saw this one's claim when it asked, and refuses (or backs off, if it serves)
            log.warning("bridge %s: another bridge (claim %s) is starting on this name; it must refuse",
                        self._base, claim)


async def _live_keys(s: Any, key: str, timeout_s: float) -> set[str]:
    """The keys of the liveliness tokens matching ``key`` that Zenoh knows of (a liveliness get, awaited)."""
    from aioadept.bus import zenoh as zb

    loop = asyncio.get_running_loop()
    done: asyncio.Future[None] = loop.create_future()
    keys: set[str] = set()

    def on_reply(rep: Any) -> None:  # a Zenoh thread: hand over
        if rep.ok is not None:
            _call_soon(loop, keys.add, str(rep.ok.key_expr))

    def on_done() -> None:
        _call_soon(loop, lambda: done.done() or done.set_result(None))

    s.liveliness().get(key, zb._zenoh().handlers.Callback(on_reply, on_done), timeout=timeout_s)
    await asyncio.wait_for(done, timeout_s + 5.0)
    return keys


def _call_soon(loop: asyncio.AbstractEventLoop, fn: Any, *args: Any) -> None:
    try:
        loop.call_soon_threadsafe(fn, *args)
    except RuntimeError:  # the loop is closed
        pass
