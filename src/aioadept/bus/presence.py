"""Node presence on the Zenoh transport: who is in the cell, learnt at once.

Each node process declares a liveliness token ``aioadept/<cell>/<node>`` (:func:`aioadept.bus.zenoh.declare_node`,
as it prints READY). :class:`NodeWatcher` subscribes to the tokens of a cell and reports each node appearing and
vanishing as Zenoh's liveliness says it: a killed process's token goes with its TCP link to the router, so there is
no timeout to wait for. Zenoh calls back on its own thread; the callback only hands the event to the loop with
``call_soon_threadsafe``.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Any

from aioadept.bus.zenoh import ROOT, _zenoh, check_key, session

__all__ = ["NodeWatcher", "PresenceEvent"]

@dataclass(frozen=True, slots=True)
class PresenceEvent:
    """Node ``node`` of cell ``cell`` appeared (``alive``) or vanished; ``key`` is its liveliness key."""

    cell: str
    node: str
    alive: bool
    key: str


@dataclass
class NodeWatcher:
    """Watch the nodes of ``cell`` (``"*"``: every cell) come and go, as Zenoh liveliness reports them.

    ``async with NodeWatcher("demo") as w: async for ev in w: ...`` yields :class:`PresenceEvent` s, starting with
    every node already alive; ``w.alive`` is the set of live node names, ``await w.wait_for(node, alive, timeout_s)``
    waits for one change (raises TimeoutError).
    """

    cell: str = "*"
    alive: set[str] = field(default_factory=set)

    def __post_init__(self) -> None:
        self._queue: asyncio.Queue[PresenceEvent] = asyncio.Queue()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._sub: Any = None
        self._changed: asyncio.Event | None = None

    async def __aenter__(self) -> NodeWatcher:
        zenoh = _zenoh()
        self._loop = asyncio.get_running_loop()
        self._changed = asyncio.Event()
        key = check_key(f"{ROOT}/{self.cell}/*", wildcards=True)
        self._sub = session().liveliness().declare_subscriber(
            key, zenoh.handlers.Callback(self._on_sample), history=True)
        return self

    async def __aexit__(self, *exc: object) -> None:
        sub, self._sub = self._sub, None
        if sub is not None:
            sub.undeclare()

    def _on_sample(self, sample: Any) -> None:  # a Zenoh thread
        key = str(sample.key_expr)
        parts = key.split("/")
        if len(parts) != 3:
            return
        alive = sample.kind == _zenoh().SampleKind.PUT
        ev = PresenceEvent(parts[1], parts[2], alive, key)
        try:
            assert self._loop is not None
            self._loop.call_soon_threadsafe(self._deliver, ev)
        except RuntimeError:
            pass

    def _deliver(self, ev: PresenceEvent) -> None:
        (self.alive.add if ev.alive else self.alive.discard)(ev.node)
        self._queue.put_nowait(ev)
        assert self._changed is not None
        self._changed.set()

    async def wait_for(self, node: str, alive: bool, timeout_s: float) -> None:
        """Wait until ``node`` is alive (``alive=True``) or gone; TimeoutError after ``timeout_s``."""
        assert self._changed is not None
        async with asyncio.timeout(timeout_s):
            while (node in self.alive) != alive:
                self._changed.clear()
                await self._changed.wait()

    def __aiter__(self) -> AsyncIterator[PresenceEvent]:
        return self._iterate()

    async def _iterate(self) -> AsyncIterator[PresenceEvent]:
        while True:
            yield await self._queue.get()
