"""A stand-in part locator for tests of pick and place's motion sequence: it answers from the world's truth on the
sim's ``world.state`` stream, not from an image. Never the app's default (``aioadept pickplace`` asks the vision
node's locator); it lets the motion sequence be tested apart from the camera and its calibration.
"""

from __future__ import annotations

import time
from typing import Any

from aioadept.apps.pickplace import LocateAnswer
from aioadept.bus.located import LocatedPart
from aioadept.apps.pickplace_run import WorldWatch
from aioadept.world import WorldConfig


class WorldTruthLocator:
    """Parts where a ``WorldState`` published after the request puts them (top-face centre, heading), offset by
    ``offset_mm`` (x, y): an offset makes the "part is not where the locator says" fault. ``fail``: raise this
    instead of answering. An async context manager (it subscribes to ``state_endpoint``)."""

    def __init__(self, state_endpoint: str, world: WorldConfig, *, offset_mm: tuple[float, float] = (0.0, 0.0),
                 fail: BaseException | None = None) -> None:
        self.world = world
        self.offset_mm = offset_mm
        self.fail = fail
        self.requests = 0
        self._watch = WorldWatch(state_endpoint)

    async def __aenter__(self) -> WorldTruthLocator:
        await self._watch.__aenter__()
        return self

    async def __aexit__(self, *exc: Any) -> None:
        await self._watch.__aexit__(*exc)

    async def locate(self) -> LocateAnswer:
        self.requests += 1
        if self.fail is not None:
            raise self.fail
        t0 = time.perf_counter()
        ws = await self._watch.fresh(5.0)  # after the request: the feeder may just have brought a part
        if ws is None:
            raise TimeoutError("no world.state within 5 s")
        parts = []
        for st in ws.parts:
            if st.grasped:
                continue
            spec = self.world.part(st.id)
            parts.append(LocatedPart(st.pose.x + self.offset_mm[0], st.pose.y + self.offset_mm[1],
                                     st.pose.z + spec.height_mm, st.heading_deg, marker=spec.marker))
        return LocateAnswer(tuple(parts), (time.perf_counter() - t0) * 1000.0)
