"""A stand-in part locator for tests of pick and place's motion sequence: it answers from the world's truth on the
sim's ``world.state`` stream, not from an image. Never the app's default (``aioadept pickplace`` asks the vision
node's locator); it lets the motion sequence be tested apart from the camera and its calibration.
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

from aioadept.apps.pickplace import LocateAnswer, LocatedPart
from aioadept.worldmodel import WorldConfig


class WorldTruthLocator:
    """Parts where the latest ``WorldState`` puts them (top-face centre, heading), offset by ``offset_mm`` (x, y):
    an offset makes the "part is not where the locator says" fault. ``fail``: raise this instead of answering."""

    def __init__(self, state_endpoint: str, world: WorldConfig, *, offset_mm: tuple[float, float] = (0.0, 0.0),
                 fail: BaseException | None = None) -> None:
        self.endpoint = state_endpoint
        self.world = world
        self.offset_mm = offset_mm
        self.fail = fail
        self.requests = 0
        self._sub: Any = None
        self._latest: Any = None
        self._task: asyncio.Task | None = None

    async def __aenter__(self) -> WorldTruthLocator:
        from aioadept.bus import Subscriber
        from aioadept.bus.messages import WORLD_STATE_TOPIC

        self._sub = await Subscriber(self.endpoint, topics=[WORLD_STATE_TOPIC]).__aenter__()
        self._task = asyncio.create_task(self._follow())
        return self

    async def __aexit__(self, *exc: Any) -> None:
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
        await self._sub.__aexit__(*exc)

    async def _follow(self) -> None:
        from aioadept.bus.messages import WorldState

        while True:
            _topic, payload = await self._sub.recv()
            self._latest = WorldState.from_bytes(payload)

    async def locate(self) -> LocateAnswer:
        self.requests += 1
        if self.fail is not None:
            raise self.fail
        t0 = time.perf_counter()
        # A fresh sample: one published after the request (the feeder may just have brought a part).
        before = self._latest
        async with asyncio.timeout(5.0):
            while self._latest is before or self._latest is None:
                await asyncio.sleep(0.002)
        ws = self._latest
        parts = []
        for st in ws.parts:
            if st.grasped:
                continue
            spec = self.world.part(st.id)
            parts.append(LocatedPart(st.pose.x + self.offset_mm[0], st.pose.y + self.offset_mm[1],
                                     st.pose.z + spec.height_mm, st.heading_deg, spec.marker))
        return LocateAnswer(tuple(parts), (time.perf_counter() - t0) * 1000.0)
