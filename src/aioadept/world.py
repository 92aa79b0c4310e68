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
- The feeder's queue (``queue`` parts, :func:`fed_parts`) brings the next part
  ``interval_s`` (robot time) after the feeder emptied: after no part's centre, held or not, has lain in its
  rectangle for that long (the previous part left it, in the hand or not). A part still queued is not in the world
  (not in a snapshot, never grasped). :meth:`World.step` makes it arrive; the controller calls it whenever its
  I/O advances, so both backends and the state stream see the same arrivals.

Poses are 4 x 4 matrices inside and :class:`~aioadept.geometry.Pose` values (Adept Z-Y-Z) outside.

The values (configuration, part states, events, snapshots) are pure values and a little geometry, shared by
:class:`World` (the behaviour), the bus (:class:`aioadept.bus.messages.WorldState`), the virtual camera
(:mod:`aioadept.vision.world_camera`) and the recording. Part frames: the origin at the centre of the bottom face,
z up. :attr:`PartState.heading_deg` is the rotation about the world z axis of a part lying flat (Adept Z-Y-Z puts
it in ``roll`` at pitch 0, which reads badly). The cell file's ``[world]`` table is read by
:mod:`aioadept.cell.world`.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from aioadept.geometry import Pose, inverse_transform

SHAPES = ("box", "cylinder")
"""Part shapes: a box (``size_mm`` = length along the part's x, width along y, height) or an upright cylinder
(``size_mm`` = diameter, diameter, height)."""

COLOURS: dict[str, tuple[int, int, int]] = {
    "red": (200, 40, 40), "green": (40, 160, 60), "blue": (40, 70, 200), "yellow": (230, 200, 40),
    "orange": (235, 130, 30), "white": (235, 235, 235), "grey": (128, 128, 128), "black": (30, 30, 30),
}
"""Colour names a cell file may use (RGB); a list of three 0..255 numbers works too."""

# -------------------------------------------------------------------------------------------------- the config
@dataclass(frozen=True, slots=True)
class PartSpec:
    """One part as the cell file places it: lying flat on the table at (``x_mm``, ``y_mm``), turned ``yaw_deg``
    about z. ``marker``: the ArUco id printed on its top face, or None: a ``marker_mm`` square (black border
    included) on a white label (:func:`label_mm`), centred, the marker's x axis along the part's x and its y
    along the part's y (OpenCV's marker frame: the image's top-left corner at (-s/2, +s/2))."""

    id: int
    shape: str = "box"
    size_mm: tuple[float, float, float] = (40.0, 30.0, 20.0)
    colour: tuple[int, int, int] = COLOURS["red"]
    marker: int | None = None
    marker_mm: float = 15.0
    x_mm: float = 0.0
    y_mm: float = 0.0
    yaw_deg: float = 0.0
    fed: int = 0
    """0: on the table from the start. k >= 1: the k-th part the feeder's queue brings (:class:`Feeder`); it is not
    in the world until it arrives, at (``x_mm``, ``y_mm``, ``yaw_deg``) in the feeder."""

    @property
    def height_mm(self) -> float:
        return self.size_mm[2]


@dataclass(frozen=True, slots=True)
class Feeder:
    """Where parts arrive: a rectangle centred at (``x_mm``, ``y_mm``), ``width_mm`` along x, ``depth_mm`` along y;
    ``sensor``: the digital input (1001..1512) that is on while a part lies in it."""

    x_mm: float
    y_mm: float
    width_mm: float = 80.0
    depth_mm: float = 80.0
    sensor: int = 1002
    queue: int = 0
    """Parts the feeder brings one after another (:func:`fed_parts`; 0: none, only the parts listed)."""
    template: int | None = None
    """The id of the part whose shape, size, colour and marker the fed parts copy (None: the first listed)."""
    interval_s: float = 0.5
    """The next part arrives this long (robot time: divided by the sim's time scale) after the feeder emptied."""
    jitter_mm: float = 0.0
    """Each fed part lies within +-``jitter_mm`` of the feeder's centre in x and in y (uniform)."""
    jitter_deg: float = 0.0
    """... turned within +-``jitter_deg`` of the template's yaw (uniform)."""
    seed: int = 0
    """Seed of the jitter: the same cell file feeds the same parts."""

    def contains(self, x_mm: float, y_mm: float) -> bool:
        return abs(x_mm - self.x_mm) <= self.width_mm / 2 and abs(y_mm - self.y_mm) <= self.depth_mm / 2


@dataclass(frozen=True, slots=True)
class Pallet:
    """Place targets: ``rows`` x ``cols`` slots, slot (0, 0) centred at (``x_mm``, ``y_mm``), columns
    ``pitch_x_mm`` apart along the pallet's x, rows ``pitch_y_mm`` apart along its y, the pallet turned ``yaw_deg``
    about z. Slots are numbered row by row from 0."""

    x_mm: float
    y_mm: float
    yaw_deg: float = 0.0
    rows: int = 2
    cols: int = 3
    pitch_x_mm: float = 60.0
    pitch_y_mm: float = 60.0

    @property
    def slots(self) -> int:
        return self.rows * self.cols

    def slot_xy(self, index: int) -> tuple[float, float, float]:
        """(x mm, y mm, heading deg) of slot ``index`` on the table; IndexError outside 0..slots-1."""
        if not 0 <= index < self.slots:
            raise IndexError(f"pallet slot {index} outside 0..{self.slots - 1}")
        r, c = divmod(index, self.cols)
        a = math.radians(self.yaw_deg)
        dx, dy = c * self.pitch_x_mm, r * self.pitch_y_mm
        return (self.x_mm + dx * math.cos(a) - dy * math.sin(a), self.y_mm + dx * math.sin(a) + dy * math.cos(a),
                self.yaw_deg)


@dataclass(frozen=True, slots=True)
class WorldCamera:
    """The fixed camera above the table (the virtual camera's model: :class:`aioadept.vision.virtual_camera.
    LensOptics`). ``pose``: the camera frame in the world, OpenCV axes (z along the optical axis, x right, y down);
    the default looks straight down from ``z_mm`` above the point (``x_mm``, ``y_mm``). The lens is focused on the
    table top."""

    x_mm: float = 450.0
    y_mm: float = 0.0
    z_mm: float = 900.0
    yaw_deg: float = 0.0
    """Turn of the camera about the vertical (0: image x along world -x, image y along world +y)."""
    focal_length_mm: float = 8.0
    f_number: float = 8.0
    noise_sigma: float = 2.0
    width_px: int = 1024
    height_px: int = 768

    def pose(self) -> Pose:
        """The camera frame in the world: at (x, y, z), looking down (pitch 180), turned ``yaw_deg`` about z."""
        return Pose(self.x_mm, self.y_mm, self.z_mm, self.yaw_deg, 180.0, 0.0)


@dataclass(frozen=True, slots=True)
class ToolMarker:
    """An ArUco marker carried by the robot's tool, for ``aioadept calibrate`` (eye-to-hand): a flat plate
    ``offset_mm`` along the tool's z from the tool point, facing back up the tool axis (so the fixed camera sees it
    when the tool points down), its x along the tool's x. ``marker_mm``: the marker's side, black border included
    (printed on a white label one module wider each side)."""

    marker: int
    marker_mm: float = 40.0
    offset_mm: float = 5.0

    def mount(self) -> np.ndarray:
        """The marker's frame in the tool's (4 x 4): z out of the plate, towards the camera."""
        return Pose(0.0, 0.0, self.offset_mm, 0.0, 180.0, 0.0).to_matrix()


@dataclass(frozen=True, slots=True)
class WorldConfig:
    """The whole world of a cell (the cell file's ``[world]`` table, :mod:`aioadept.cell.world`)."""

    table_z_mm: float = 0.0
    """Height of the table top in the robot's world frame."""
    parts: tuple[PartSpec, ...] = ()
    feeder: Feeder | None = None
    pallet: Pallet | None = None
    camera: WorldCamera | None = None
    grip_tolerance_mm: float = 3.0
    snap_mm: float = 3.0
    grip_tilt_deg: float = 10.0
    aruco_dict: str = "DICT_4X4_50"
    tool_marker: ToolMarker | None = None
    """The marker on the tool the world's camera draws at the robot's tool pose (``[world.tool_marker]``), or
    None."""

    def part(self, part_id: int) -> PartSpec:
        for p in self.parts:
            if p.id == part_id:
                return p
        raise KeyError(part_id)


# -------------------------------------------------------------------------------------------------- the state
@dataclass(frozen=True, slots=True)
class PartState:
    """One part at one time: ``pose`` of its frame in the world, ``grasped`` (in the hand), ``dropped`` (it fell:
    released too high)."""

    id: int
    pose: Pose
    grasped: bool = False
    dropped: bool = False

    @property
    def heading_deg(self) -> float:
        """Rotation about the world z axis (of the part's x axis), degrees in (-180, 180]."""
        m = self.pose.to_matrix()
        return math.degrees(math.atan2(m[1, 0], m[0, 0]))


@dataclass(frozen=True, slots=True)
class WorldEvent:
    """Something that happened in the world at server time ``t_s``: ``kind`` is ``grasped``, ``released``,
    ``dropped`` (an error: a part fell), ``fed`` (the feeder's queue brought it) or ``sensor`` (``signal`` turned ``on``). ``seq`` runs over all events."""

    seq: int
    t_s: float
    kind: str
    part: int = -1
    signal: int = 0
    on: bool = False
    text: str = ""

    @property
    def error(self) -> bool:
        return self.kind == "dropped"


@dataclass(frozen=True, slots=True)
class WorldSnapshot:
    """The world at ``t_s``, for the bus, the recording and the camera."""

    t_s: float
    parts: tuple[PartState, ...] = ()
    sensors_on: tuple[int, ...] = field(default=())

    def part(self, part_id: int) -> PartState:
        for p in self.parts:
            if p.id == part_id:
                return p
        raise KeyError(part_id)


def fed_parts(feeder: Feeder, template: PartSpec, first_id: int,
              free_markers: tuple[int, ...] = ()) -> tuple[PartSpec, ...]:
    """The ``feeder.queue`` parts the feeder brings, in order: copies of ``template`` with ids from ``first_id``,
    each at the feeder's centre plus its jitter (seeded: pure). A marked template's copies take the ids of
    ``free_markers`` (the dictionary's ids no listed part uses) in turn, from the first after the template's: every
    fed part has its own marker until the dictionary runs out, then they repeat."""
    rng = np.random.default_rng(feeder.seed)
    start = sum(1 for m in free_markers if template.marker is not None and m < template.marker)
    out = []
    for k in range(1, feeder.queue + 1):
        dx, dy = rng.uniform(-1.0, 1.0, 2) * feeder.jitter_mm
        dyaw = float(rng.uniform(-1.0, 1.0)) * feeder.jitter_deg
        marker = template.marker
        if marker is not None and free_markers:
            marker = free_markers[(start + k - 1) % len(free_markers)]
        out.append(PartSpec(first_id + k - 1, template.shape, template.size_mm, template.colour, marker,
                            template.marker_mm, round(feeder.x_mm + float(dx), 3), round(feeder.y_mm + float(dy), 3),
                            round(template.yaw_deg + dyaw, 3), fed=k))
    return tuple(out)


def marker_bits(aruco_dict: str) -> int:
    """The data bits per side of an ArUco dictionary named like OpenCV's (``DICT_4X4_50`` -> 4)."""
    return int(aruco_dict.split("_")[1].split("X")[0])


def label_mm(marker_mm: float, aruco_dict: str) -> float:
    """Side of the white label a marker is printed on: the marker (``marker_mm``, its black border included, the
    length OpenCV's pose estimation takes) with a white margin of one module on each side, which detection needs
    around the border."""
    bits = marker_bits(aruco_dict)
    return marker_mm * (bits + 4) / (bits + 2)


def flat_matrix(x_mm: float, y_mm: float, z_mm: float, heading_deg: float) -> np.ndarray:
    """The 4 x 4 frame of a part lying flat at (x, y, z) turned ``heading_deg`` about z."""
    a = math.radians(heading_deg)
    m = np.eye(4)
    m[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    m[:3, 3] = (x_mm, y_mm, z_mm)
    return m


__all__ = [
    "COLOURS", "SHAPES", "Feeder", "Pallet", "PartSpec", "PartState", "WorldCamera", "WorldConfig", "WorldEvent",
    "WorldSnapshot", "fed_parts", "flat_matrix", "label_mm", "marker_bits",
]


# -------------------------------------------------------------------------------------------- the behaviour
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
