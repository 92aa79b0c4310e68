"""The simulated world of a cell: a table plane, parts on it, a feeder with a part-present sensor, a pallet grid.

Pure, like :mod:`aioadept.sim.controller` (time is passed in; no threads, sockets or clock). It lives beside the
robot model: the controller owns one :class:`World` (``ctl.world``) and tells it when the hand's valves change
(:meth:`World.hand_closed`, :meth:`World.hand_opened`) with the tool pose at that time, so both sim backends (the
Python skills and the V+ emulator's ``OPENI``/``CLOSEI``/``SIGNAL``) move the same parts. The state stream
publishes :meth:`World.snapshot`; the virtual camera renders it (:mod:`aioadept.vision.world_camera`).

Rules (docs/sim.md, "The world"):

- A part is grasped when the hand starts closing while the tool centre point (TCP, ``HERE``) is within
  ``grip_tolerance_mm`` of the part's vertical axis and between its bottom (less the tolerance) and its top (the
  fingertips are beside it), with the tool's z axis pointing down within ``grip_tilt_deg``. The nearest such
  part wins. From then on it is rigidly attached to the tool (the transform at the grasp is kept: no centring)
  and the closing fingers stop on it, so the closed-fully switch stays off; without a part they close fully
  ("closed on nothing").
- Opening or relaxing the hand releases the part at the tool's pose. A part whose bottom is within ``snap_mm`` of
  the table top is set on the table (z snapped to the plane, upright, its heading kept). From higher up it falls:
  an error event (``dropped``) is logged and published and the part lies on the table below where it was
  released, marked ``dropped``; it is never moved silently.
- Parts rest on the table plane only: no collisions, no stacking, no pushing (a part released over another one
  overlaps it).
- The feeder's sensor (a digital input) is on while the centre of any part that is not in the hand lies inside
  the feeder's rectangle.
- The feeder's queue (``queue`` parts, :func:`aioadept.worldmodel.fed_parts`) brings the next part
  ``interval_s`` (robot time) after the feeder emptied: after no part's centre, held or not, has lain in its
  rectangle for that long (the previous part left it, in the hand or not). A part still queued is not in the world
  (not in a snapshot, never grasped). :meth:`World.step` makes it arrive; the controller calls it whenever its
  I/O advances, so both backends and the state stream see the same arrivals.

The values (configuration, part states, events, snapshots) live in :mod:`aioadept.worldmodel`.
Poses are 4 x 4 matrices inside and :class:`~aioadept.geometry.Pose` values (Adept Z-Y-Z) outside.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from aioadept.geometry import Pose, inverse_transform
from aioadept.worldmodel import (PartState, WorldConfig,
                                 WorldEvent, WorldSnapshot, flat_matrix)

MAX_EVENTS = 4096
"""Events kept in :attr:`World.events` (the state stream reads them at >= 10 Hz)."""


class World:
    """The parts and sensors of a :class:`WorldConfig`; see the module docstring. All times are server seconds."""

    def __init__(self, config: WorldConfig, *, time_scale: float = 1.0) -> None:
        self.config = config
        self.time_scale = float(time_scale)
        """The sim's time scale: the feeder's interval shrinks with it, as motion does."""
        ids = [p.id for p in config.parts]
        if len(set(ids)) != len(ids):
            raise ValueError(f"part ids must be unique, got {ids}")
        self._pose: dict[int, np.ndarray] = {
            p.id: flat_matrix(p.x_mm, p.y_mm, config.table_z_mm, p.yaw_deg) for p in config.parts}
        self._dropped: set[int] = set()
        self.held: int | None = None
        """The id of the part in the hand, or None."""
        self._grip: np.ndarray | None = None  # the held part's frame in the tool frame
        self.events: deque[WorldEvent] = deque(maxlen=MAX_EVENTS)
        self._seq = 0
        self._sensor_on = False
        self._waiting: deque[int] = deque(p.id for p in sorted(config.parts, key=lambda p: p.fed) if p.fed)
        """The fed parts still queued, next first: not in the world yet."""
        self._empty_since: float | None = -math.inf  # an empty feeder gets its first part at once
        self._now = 0.0
        self._update_sensor(0.0)
        self.step(0.0)

    # -- the hand ------------------------------------------------------------------------------------------
    def grasp_candidate(self, tool: Pose) -> int | None:
        """The part the fingers would close on with the TCP at ``tool`` (see the module docstring), or None."""
        c = self.config
        m = tool.to_matrix()
        if m[2, 2] > -math.cos(math.radians(c.grip_tilt_deg)):
            return None  # the tool does not point down
        tcp = m[:3, 3]
        best: tuple[float, int] | None = None
        for spec in c.parts:
            if spec.id == self.held or spec.id in self._waiting:
                continue
            pm = self._pose[spec.id]
            local = inverse_transform(pm) @ np.append(tcp, 1.0)
            lx, ly, lz = local[:3]
            if not -c.grip_tolerance_mm <= lz < spec.height_mm:
                continue  # the fingertips must be beside the part, not above or under it
            dist = math.hypot(lx, ly)
            if dist > c.grip_tolerance_mm:
                continue  # the TCP must be within the tolerance of the part's vertical axis
            if best is None or dist < best[0]:
                best = (dist, spec.id)
        return None if best is None else best[1]

    def hand_closed(self, t_s: float, tool: Pose) -> list[WorldEvent]:
        """The hand starts closing at ``t_s`` with the TCP at ``tool``: grasp the part between the fingers, if any
        (:attr:`held` says whether the fingers stop on a part). Returns the events."""
        out: list[WorldEvent] = []
        if self.held is not None:
            return out  # closing again on the part already held
        part = self.grasp_candidate(tool)
        if part is None:
            return out
        self.held = part
        self._dropped.discard(part)
        self._grip = inverse_transform(tool.to_matrix()) @ self._pose[part]
        out.append(self._event(t_s, "grasped", part=part))
        out += self._update_sensor(t_s)
        return out

    def hand_opened(self, t_s: float, tool: Pose) -> list[WorldEvent]:
        """The hand opens (or relaxes) at ``t_s`` with the TCP at ``tool``: release the held part (set on the table,
        or dropped with an error event). Returns the events."""
        if self.held is None:
            return []
        part, grip = self.held, self._grip
        assert grip is not None
        self.held, self._grip = None, None
        m = tool.to_matrix() @ grip
        c = self.config
        spec = c.part(part)
        heading = math.degrees(math.atan2(m[1, 0], m[0, 0]))
        # The lowest point of the part's bottom face decides where it rests (an upright part: its origin).
        gap = float(m[2, 3]) - c.table_z_mm
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(m[2, 2])))))
        self._pose[part] = flat_matrix(float(m[0, 3]), float(m[1, 3]), c.table_z_mm, heading)
        out: list[WorldEvent] = []
        if abs(gap) <= c.snap_mm and tilt <= c.grip_tilt_deg:
            out.append(self._event(t_s, "released", part=part,
                                   text=f"part {part} set on the table at x={m[0, 3]:.1f} y={m[1, 3]:.1f} mm"))
        else:
            self._dropped.add(part)
            why = (f"{gap:.1f} mm above the table" if gap > c.snap_mm else
                   f"{-gap:.1f} mm below the table top (collisions are not modelled)" if gap < -c.snap_mm else
                   f"tilted {tilt:.0f} deg")
            out.append(self._event(t_s, "dropped", part=part,
                                   text=f"part {part} ({spec.shape}) dropped: released {why} at x={m[0, 3]:.1f} "
                                        f"y={m[1, 3]:.1f} mm; it now lies on the table there"))
        out += self._update_sensor(t_s)
        return out

    # -- reading -------------------------------------------------------------------------------------------
    def part_matrix(self, part: int, tool: Pose | None = None) -> np.ndarray:
        """The 4 x 4 frame of ``part``; a held part's follows ``tool`` (the TCP now), if given."""
        if part == self.held and tool is not None:
            assert self._grip is not None
            return tool.to_matrix() @ self._grip
        return self._pose[part]

    def snapshot(self, t_s: float, tool: Pose | None = None) -> WorldSnapshot:
        """Every part's pose at ``t_s`` (``tool``: the TCP at ``t_s``, which a held part follows)."""
        parts = tuple(PartState(p.id, Pose.from_matrix(self.part_matrix(p.id, tool)), p.id == self.held,
                                p.id in self._dropped) for p in self.config.parts if p.id not in self._waiting)
        feeder = self.config.feeder
        on = (feeder.sensor,) if feeder is not None and self._sensor_on else ()
        return WorldSnapshot(t_s, parts, on)

    # -- the feeder's queue ----------------------------------------------------------------------------------
    @property
    def queued(self) -> int:
        """Fed parts not arrived yet."""
        return len(self._waiting)

    def step(self, t_s: float, tool: Pose | None = None) -> list[WorldEvent]:
        """Advance the feeder's queue to ``t_s`` (``tool``: the TCP then, which a held part follows): the next part
        arrives once the feeder has been empty for ``interval_s`` / time scale. Earlier times than one seen before
        change nothing. Returns the events (``fed``, then the sensor's)."""
        feeder = self.config.feeder
        if feeder is None or not self._waiting or t_s < self._now:
            return []
        self._now = t_s
        occupied = any(feeder.contains(float(m[0, 3]), float(m[1, 3]))
                       for pid in self._pose if pid not in self._waiting
                       for m in (self.part_matrix(pid, tool),))
        if occupied:
            self._empty_since = None
            return []
        if self._empty_since is None:
            self._empty_since = t_s
        if t_s < self._empty_since + feeder.interval_s / self.time_scale:
            return []
        part = self._waiting.popleft()
        self._empty_since = None
        spec = self.config.part(part)
        out = [self._event(t_s, "fed", part=part, text=f"part {part} fed at x={spec.x_mm:.1f} y={spec.y_mm:.1f} "
                                                      f"mm, yaw {spec.yaw_deg:.1f} deg ({len(self._waiting)} queued)")]
        return out + self._update_sensor(t_s)

    def next_feed_s(self) -> float | None:
        """When the next part is due, if the feeder is empty and parts are queued (else None)."""
        feeder = self.config.feeder
        if feeder is None or not self._waiting or self._empty_since is None:
            return None
        return self._empty_since + feeder.interval_s / self.time_scale

    def sensor_on(self) -> bool:
        """The feeder's part-present sensor (False without a feeder)."""
        return self._sensor_on

    def events_since(self, seq: int) -> tuple[list[WorldEvent], int]:
        """The events after sequence number ``seq`` and the number to ask from next time."""
        return [e for e in self.events if e.seq > seq], self._seq

    # -- inside --------------------------------------------------------------------------------------------
    def _event(self, t_s: float, kind: str, **kw) -> WorldEvent:
        self._seq += 1
        ev = WorldEvent(self._seq, t_s, kind, **kw)
        self.events.append(ev)
        return ev

    def _update_sensor(self, t_s: float) -> list[WorldEvent]:
        feeder = self.config.feeder
        if feeder is None:
            return []
        on = any(feeder.contains(float(m[0, 3]), float(m[1, 3]))
                 for pid, m in self._pose.items() if pid != self.held and pid not in self._waiting)
        if on == self._sensor_on:
            return []
        self._sensor_on = on
        return [self._event(t_s, "sensor", signal=feeder.sensor, on=on)]


__all__ = ["MAX_EVENTS", "World"]
