"""The vision node's options as one dataclass: the single schema of a ``[vision]`` table, for both ``aioadept
vision --config FILE`` and the cell file of ``demo``/``focus``/``experiment`` (``examples/cell.toml``).

:class:`VisionOptions` lists every option with its type and default; :meth:`VisionOptions.from_table` checks a TOML
table against it once (unknown keys, wrong types, bad values), with errors naming the file and the key
(:class:`aioadept.errors.ConfigError`). :data:`SOURCES` is the registry of camera sources a ``source`` spec may
name. Importing this module loads neither OpenCV nor ZeroMQ.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from aioadept.cell.schema import Range, check_ranges, ranged
from aioadept.defaults import REQUEST_ENDPOINT, RESPONSE_ENDPOINT, STATE_ENDPOINT

SOURCES: dict[str, str] = {
    "virtual": "the virtual camera, rendering the calibration object at the robot's tool pose (no argument)",
    "world": "the fixed camera above the table, rendering the simulated world's parts (no argument; needs world)",
    "gige": "gige:ADDRESS, a GigE Vision camera's IPv4 address (opened by address; needs the [gige] extra)",
    "folder": "folder:PATH, images of a folder (a --save-frames folder replays with its times)",
    "opencv": "opencv:SPEC, an OpenCV capture: device index, video file or URL",
}
"""Source kinds -> what the spec means; ``aioadept.vision.service.make_sources`` builds one camera per spec."""

POLICIES = ("nearest", "after")
TRIGGERS = ("auto", "software", "free")
GRAPHS = ("sharpness", "frame-sharpness", "noop", "locate")
GRAPH_THREADS = ("auto", "always", "never")


def check_source(spec: Any) -> str:
    """``spec`` if it names a registered source (with its argument where one is needed); ValueError otherwise."""
    if not isinstance(spec, str):
        raise ValueError(f"expected a source spec string, got {spec!r}")
    kind, sep, arg = spec.partition(":")
    bare = kind in ("virtual", "world")
    if kind not in SOURCES or (bare and sep) or (not bare and not arg):
        raise ValueError(f"bad source {spec!r}: use virtual, world, gige:ADDRESS, folder:PATH or opencv:SPEC")
    return spec


@dataclass(slots=True)
class VisionOptions:
    """Every option of ``aioadept vision`` (the long option names with ``_``), with its default."""

    source: str | list[str] = "virtual"
    """One source spec or a list of them (several cameras); see :data:`SOURCES`."""
    state_endpoint: str = STATE_ENDPOINT
    request_endpoint: str = REQUEST_ENDPOINT
    """The node's request SUB, CZMQ style from the node's side: bare connects (the MCN binds it, as pyadept's
    PubSubPair does), ``@`` makes the node bind it (the MCN connects); see docs/interfaces.md."""
    response_endpoint: str = RESPONSE_ENDPOINT
    """The node's response PUB: bare binds (the MCN connects), ``>`` makes the node connect to the MCN's SUB."""
    fps: float = ranged(15.0, Range(0.0, lo_open=True))
    buffer_size: int = ranged(64, Range(1, integer=True))
    focus_offset_mm: float = ranged(20.0, Range(0.0, unit="mm"))
    """Virtual camera: how far along tool z beyond the approach pose the focal plane lies. Not negative: the sweep
    steps along +z from the approach pose, so a plane behind it would be reported at the approach pose."""
    working_distance_mm: float = ranged(300.0, Range(0.0, lo_open=True, unit="mm"))
    f_number: float = ranged(2.8, Range(0.0, lo_open=True))
    noise_sigma: float = ranged(2.0, Range(0.0))
    seed: int | None = None
    policy: str = "after"
    """Frame choice: "nearest" in time to the request (the paper), or the first frame "after" it."""
    max_frame_age: float = 0.1
    trigger: str = "auto"
    """Acquisition: "auto" (each request software-triggers its own exposure on cameras that can), "software"
    (insist: an error for a camera that cannot), "free" (free-running at ``fps``)."""
    exposure_ms: float = 5.0
    """Exposure time, ms: the virtual camera's, and written to a GigE camera (``source = "gige:ADDRESS"``)."""
    pixel_format: str = "Mono8"
    """GigE cameras: the PixelFormat written at open (Mono8, Mono16, Bayer..8)."""
    readout_ms: float | None = None
    frame_timeout: float = ranged(1.0, Range(0.0, lo_open=True, unit="s"))
    graph: str = "sharpness"
    calibration: str | None = None
    """``graph = "locate"``: the cell file with the ``[calibration]`` table (:mod:`aioadept.vision.calibration`)."""
    part_height_mm: float | None = ranged(None, Range(-1000.0, 2000.0, unit="mm"))
    marker_mm: float = ranged(15.0, Range(0.1, 1000.0, unit="mm"))
    aruco_dict: str = "DICT_4X4_50"
    graph_thread: str = "auto"
    graph_inline_max_ms: float = ranged(5.0, Range(0.0, unit="ms"))
    inline: bool = False
    save_frames: str | None = None
    figures: str | None = None
    log_level: str = "INFO"
    curve_secret: str | None = None
    state_curve_secret: str | None = None
    state_curve_server: str | None = None
    curve_allow: str | list[str] | None = None
    max_state_age: float = 0.5
    max_queue: int = 32
    max_request_bytes: int = 1 << 20
    world: str | None = None
    """The simulated world the ``world`` source renders: a cell file (its ``[world]`` table) or the ``.json`` a
    starter writes (aioadept.cell.world); its ``[world.camera]`` places the camera."""

    @classmethod
    def from_table(cls, table: Any, where: str) -> VisionOptions:
        """The options of a TOML table (keys with ``_`` or ``-``), checked once; ``where`` names the file and table
        in messages (``"cell.toml [vision]"``). Raises :class:`~aioadept.errors.ConfigError`."""
        from aioadept.cell.schema import check_section
        from aioadept.errors import ConfigError

        if isinstance(table, dict):
            table = {str(k).replace("-", "_"): v for k, v in table.items()}
        opts = cls(**check_section(cls, table, where))
        try:
            opts.check()
        except ValueError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        return opts

    def sources(self) -> list[str]:
        return [self.source] if isinstance(self.source, str) else list(self.source)

    def check(self) -> None:
        """Values the types alone do not catch; ValueError naming the key."""
        specs = self.sources()
        if not specs:
            raise ValueError("source = []: expected at least one source")
        for spec in specs:
            try:
                check_source(spec)
            except ValueError as exc:
                raise ValueError(f"source: {exc}") from None
        for key, allowed in (("policy", POLICIES), ("trigger", TRIGGERS), ("graph", GRAPHS),
                             ("graph_thread", GRAPH_THREADS)):
            value = getattr(self, key)
            if value not in allowed:
                raise ValueError(f'{key} = "{value}": expected one of {", ".join(allowed)}')
        if not (self.aruco_dict.startswith("DICT_") and self.aruco_dict.split("_")[1][:1].isdigit()):
            raise ValueError(f'aruco_dict = "{self.aruco_dict}": expected an OpenCV ArUco dictionary name such as '
                             f'DICT_4X4_50')
        from aioadept.vision.gige import PIXEL_FORMATS

        if self.pixel_format not in PIXEL_FORMATS:
            raise ValueError(f'pixel_format = "{self.pixel_format}": expected one of {", ".join(PIXEL_FORMATS)}')
        for key in ("exposure_ms", "readout_ms"):
            value = getattr(self, key)
            if value is not None and not 0 <= value < math.inf:
                raise ValueError(f"{key} = {value!r}: expected a finite number >= 0")
        for key in ("max_state_age", "max_frame_age"):
            if not getattr(self, key) > 0:
                raise ValueError(f"{key} = {getattr(self, key)!r}: expected seconds > 0 (inf: no check)")
        check_ranges(self)
        for key in ("max_queue", "max_request_bytes"):
            if getattr(self, key) < 1:
                raise ValueError(f"{key} = {getattr(self, key)!r}: expected an integer >= 1")
        self._check_endpoints()

    def _check_endpoints(self) -> None:
        from aioadept.bus.endpoints import is_none, parse_endpoint
        from aioadept.errors import BusError

        for key in ("request_endpoint", "response_endpoint", "state_endpoint"):
            if key == "state_endpoint" and is_none(self.state_endpoint):
                continue  # no robot state stream: the virtual camera shows the target at the approach pose
            try:
                parse_endpoint(getattr(self, key))
            except BusError as exc:
                raise ValueError(f"{key}: {exc}") from None

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(VisionOptions)}
