"""The cell file's ``[world]`` table -> :class:`aioadept.world.WorldConfig`, every value checked before anything
starts (one line naming the file, the key and what was expected: :class:`aioadept.errors.ConfigError`).

The table, as ``examples/cell.toml`` shows it::

    [world]
    table_z_mm = 0.0          # grip_tolerance_mm, snap_mm, grip_tilt_deg, aruco_dict too
    [[world.parts]]
    id = 1
    shape = "box"             # or "cylinder" (size_mm = [diameter, height])
    size_mm = [40, 30, 20]
    colour = "red"            # a name of aioadept.world.COLOURS or [r, g, b]
    marker = 3                # ArUco id on the top face (omit: none); marker_mm its side
    x_mm = 450.0
    y_mm = 150.0
    yaw_deg = 0.0
    [world.feeder]            # x_mm, y_mm, width_mm, depth_mm, sensor (an input 1001..1512); a queue of parts fed
                              # one after another: queue, template, interval_s, jitter_mm, jitter_deg, seed
    [world.pallet]            # x_mm, y_mm, yaw_deg, rows, cols, pitch_x_mm, pitch_y_mm
    [world.camera]            # x_mm, y_mm, z_mm, yaw_deg, focal_length_mm, f_number, noise_sigma, width_px, height_px
    [world.tool_marker]       # marker (an id no part uses), marker_mm, offset_mm: a marker on the tool, for
                              # aioadept calibrate (the camera draws it at the robot's tool pose)

:func:`world_to_table` gives the same table back (for a JSON file a starter hands to the sim and vision nodes:
``aioadept sim --world FILE``, ``aioadept vision --world FILE``); :func:`load_world` reads either.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aioadept.cell.schema import Range, check_ranges, check_section, ranged
from aioadept.errors import ConfigError
from aioadept.world import (COLOURS, SHAPES, Feeder, Pallet, PartSpec, ToolMarker, WorldCamera, WorldConfig,
                                 fed_parts, label_mm)

ARUCO_DICTS = {"DICT_4X4_50": 50, "DICT_4X4_100": 100, "DICT_4X4_250": 250, "DICT_5X5_50": 50,
               "DICT_5X5_100": 100, "DICT_6X6_50": 50, "DICT_6X6_250": 250}
"""ArUco dictionaries a world may use (``cv2.aruco`` names) and how many ids each holds."""

INPUT_SIGNALS = Range(1001, 1512, integer=True)
"""The feeder sensor is a digital input (V+ 1001..1512, as :data:`aioadept.sim.io.INPUTS`; a test keeps the two
equal, since the vision side that reads this file must not import the sim)."""
_XY = Range(-2000.0, 2000.0, unit="mm")
_ANGLE = Range(-360.0, 360.0, unit="deg")
_SIZE = Range(0.0, 1000.0, lo_open=True, unit="mm")


@dataclass(slots=True)
class _WorldTable:
    table_z_mm: float = ranged(0.0, Range(-2000.0, 2000.0, unit="mm"))
    grip_tolerance_mm: float = ranged(3.0, Range(0.0, 50.0, lo_open=True, unit="mm"))
    snap_mm: float = ranged(3.0, Range(0.0, 50.0, unit="mm"))
    grip_tilt_deg: float = ranged(10.0, Range(0.0, 90.0, unit="deg"))
    aruco_dict: str = "DICT_4X4_50"
    parts: list[Any] = field(default_factory=list)
    feeder: Any = None
    pallet: Any = None
    camera: Any = None
    tool_marker: Any = None


@dataclass(slots=True)
class _PartTable:
    id: int = ranged(0, Range(0, 2**31 - 1, integer=True))
    shape: str = "box"
    size_mm: list[float] = field(default_factory=lambda: [40.0, 30.0, 20.0])
    colour: str | list[int] = "red"
    marker: int | None = ranged(None, Range(0, 999, integer=True))
    marker_mm: float = ranged(15.0, Range(0.0, 1000.0, lo_open=True, unit="mm"))
    x_mm: float = ranged(0.0, _XY)
    y_mm: float = ranged(0.0, _XY)
    yaw_deg: float = ranged(0.0, _ANGLE)


@dataclass(slots=True)
class _FeederTable:
    x_mm: float = ranged(0.0, _XY)
    y_mm: float = ranged(0.0, _XY)
    width_mm: float = ranged(80.0, _SIZE)
    depth_mm: float = ranged(80.0, _SIZE)
    sensor: int = ranged(1002, INPUT_SIGNALS)
    queue: int = ranged(0, Range(0, 100_000, integer=True))
    template: int | None = ranged(None, Range(0, 2**31 - 1, integer=True))
    interval_s: float = ranged(0.5, Range(0.0, 3600.0, unit="s"))
    jitter_mm: float = ranged(0.0, Range(0.0, 500.0, unit="mm"))
    jitter_deg: float = ranged(0.0, Range(0.0, 180.0, unit="deg"))
    seed: int = ranged(0, Range(0, 2**31 - 1, integer=True))


@dataclass(slots=True)
class _PalletTable:
    x_mm: float = ranged(0.0, _XY)
    y_mm: float = ranged(0.0, _XY)
    yaw_deg: float = ranged(0.0, _ANGLE)
    rows: int = ranged(2, Range(1, 100, integer=True))
    cols: int = ranged(3, Range(1, 100, integer=True))
    pitch_x_mm: float = ranged(60.0, _SIZE)
    pitch_y_mm: float = ranged(60.0, _SIZE)


@dataclass(slots=True)
class _CameraTable:
    x_mm: float = ranged(450.0, _XY)
    y_mm: float = ranged(0.0, _XY)
    z_mm: float = ranged(900.0, Range(-2000.0, 5000.0, unit="mm"))
    yaw_deg: float = ranged(0.0, _ANGLE)
    focal_length_mm: float = ranged(8.0, Range(1.0, 300.0, unit="mm"))
    f_number: float = ranged(8.0, Range(0.5, 64.0))
    noise_sigma: float = ranged(2.0, Range(0.0, 50.0))
    width_px: int = ranged(1024, Range(16, 8192, integer=True, unit="px"))
    height_px: int = ranged(768, Range(16, 8192, integer=True, unit="px"))


@dataclass(slots=True)
class _ToolMarkerTable:
    marker: int = ranged(0, Range(0, 999, integer=True))
    marker_mm: float = ranged(40.0, Range(1.0, 500.0, unit="mm"))
    offset_mm: float = ranged(5.0, Range(-500.0, 500.0, unit="mm"))


def _table(typ: type, data: Any, where: str) -> Any:
    try:
        obj = typ(**check_section(typ, data, where))
        check_ranges(obj)
    except ConfigError:
        raise
    except ValueError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    return obj


def _colour(value: Any, where: str) -> tuple[int, int, int]:
    if isinstance(value, str):
        if value not in COLOURS:
            raise ConfigError(f'{where}: colour = "{value}": expected one of {", ".join(COLOURS)} or [r, g, b]')
        return COLOURS[value]
    if len(value) != 3 or not all(0 <= v <= 255 for v in value):
        raise ConfigError(f"{where}: colour = {value!r}: expected [r, g, b], each an integer in 0..255")
    return (int(value[0]), int(value[1]), int(value[2]))


def _part(data: Any, where: str, aruco_dict: str) -> PartSpec:
    n_ids = ARUCO_DICTS[aruco_dict]
    t = _table(_PartTable, data, where)
    if not isinstance(data, dict) or "id" not in data:
        raise ConfigError(f"{where}: id missing (each part needs a unique integer id)")
    if t.shape not in SHAPES:
        raise ConfigError(f'{where}: shape = "{t.shape}": expected one of {", ".join(SHAPES)}')
    want = 3 if t.shape == "box" else 2
    if len(t.size_mm) != want or not all(_SIZE.contains(v) for v in t.size_mm):
        shape = "[length, width, height]" if t.shape == "box" else "[diameter, height]"
        raise ConfigError(f"{where}: size_mm = {t.size_mm!r}: expected {shape} for a {t.shape}, each a number "
                          f"in {_SIZE.text}")
    size = tuple(float(v) for v in t.size_mm)
    if t.shape == "cylinder":
        size = (size[0], size[0], size[1])
    if t.marker is not None:
        if t.marker >= n_ids:
            raise ConfigError(f"{where}: marker = {t.marker}: expected an id in 0..{n_ids - 1} of the world's "
                              f"aruco_dict")
        fits = min(size[0], size[1]) if t.shape == "box" else size[0] / math.sqrt(2)
        if label_mm(t.marker_mm, aruco_dict) > fits:
            most = t.marker_mm * fits / label_mm(t.marker_mm, aruco_dict)
            raise ConfigError(f"{where}: marker_mm = {t.marker_mm:g}: the marker and its white margin do not fit "
                              f"on the part's top face (marker_mm at most {most:.1f})")
    return PartSpec(int(t.id), t.shape, size, _colour(t.colour, where), t.marker, float(t.marker_mm),
                    float(t.x_mm), float(t.y_mm), float(t.yaw_deg))


def _queue(feeder: Feeder, parts: list[PartSpec], where: str, n_ids: int) -> tuple[PartSpec, ...]:
    """The feeder's queued parts (:func:`aioadept.world.fed_parts`), checked: a template to copy, and each part
    inside the feeder's rectangle (else it would never turn the part-present sensor on)."""
    if feeder.template is None:
        if not parts:
            raise ConfigError(f"{where}: queue = {feeder.queue}: the fed parts copy a part: list one "
                              f"([[world.parts]]) or name it with template = ID")
        template = parts[0]
    else:
        template = next((p for p in parts if p.id == feeder.template), None)
        if template is None:
            raise ConfigError(f"{where}: template = {feeder.template}: no part has that id")
    if 2 * feeder.jitter_mm > min(feeder.width_mm, feeder.depth_mm):
        raise ConfigError(f"{where}: jitter_mm = {feeder.jitter_mm:g}: a fed part could lie outside the feeder "
                          f"(at most half its width and depth, {min(feeder.width_mm, feeder.depth_mm) / 2:g} mm)")
    used = {p.marker for p in parts if p.marker is not None}
    free = tuple(m for m in range(n_ids) if m not in used)
    return fed_parts(feeder, template, max(p.id for p in parts) + 1 if parts else 1, free)


def world_from_table(data: Any, where: str = "[world]") -> WorldConfig:
    """The :class:`WorldConfig` of a ``[world]`` table; :class:`ConfigError` (one line naming ``where`` and the
    key) for anything unknown, of the wrong type or out of range."""
    w = _table(_WorldTable, data, where)
    if w.aruco_dict not in ARUCO_DICTS:
        raise ConfigError(f'{where}: aruco_dict = "{w.aruco_dict}": expected one of {", ".join(ARUCO_DICTS)}')
    if not isinstance(w.parts, list):
        raise ConfigError(f"{where}: parts: expected a list of tables ([[world.parts]])")
    parts = [_part(p, f"{where} parts[{i}]", w.aruco_dict) for i, p in enumerate(w.parts)]
    for kind, values in (("id", [p.id for p in parts]), ("marker", [p.marker for p in parts if p.marker is not None])):
        dup = sorted({v for v in values if values.count(v) > 1})
        if dup:
            raise ConfigError(f"{where}: parts: {kind} {dup[0]} is used twice; each part needs its own")
    feeder = pallet = camera = None
    if w.feeder is not None:
        f = _table(_FeederTable, w.feeder, f"{where} feeder")
        feeder = Feeder(f.x_mm, f.y_mm, f.width_mm, f.depth_mm, int(f.sensor), int(f.queue),
                        None if f.template is None else int(f.template), float(f.interval_s), float(f.jitter_mm),
                        float(f.jitter_deg), int(f.seed))
        if feeder.queue:
            parts += _queue(feeder, parts, f"{where} feeder", ARUCO_DICTS[w.aruco_dict])
    if w.pallet is not None:
        p = _table(_PalletTable, w.pallet, f"{where} pallet")
        pallet = Pallet(p.x_mm, p.y_mm, p.yaw_deg, int(p.rows), int(p.cols), p.pitch_x_mm, p.pitch_y_mm)
    if w.camera is not None:
        c = _table(_CameraTable, w.camera, f"{where} camera")
        if not c.z_mm > w.table_z_mm + 2 * c.focal_length_mm:
            raise ConfigError(f"{where} camera: z_mm = {c.z_mm:g}: expected the camera above the table "
                              f"(table_z_mm {w.table_z_mm:g}) by more than twice the focal length")
        camera = WorldCamera(c.x_mm, c.y_mm, c.z_mm, c.yaw_deg, c.focal_length_mm, c.f_number, c.noise_sigma,
                             int(c.width_px), int(c.height_px))
    tool_marker = None if w.tool_marker is None else _tool_marker(w.tool_marker, f"{where} tool_marker", w.aruco_dict,
                                                                  parts)
    return WorldConfig(float(w.table_z_mm), tuple(parts), feeder, pallet, camera, float(w.grip_tolerance_mm),
                       float(w.snap_mm), float(w.grip_tilt_deg), w.aruco_dict, tool_marker)


def _tool_marker(data: Any, where: str, aruco_dict: str, parts: list[PartSpec]) -> ToolMarker:
    t = _table(_ToolMarkerTable, data, where)
    if not isinstance(data, dict) or "marker" not in data:
        raise ConfigError(f"{where}: marker missing (the ArUco id on the tool)")
    n_ids = ARUCO_DICTS[aruco_dict]
    if t.marker >= n_ids:
        raise ConfigError(f"{where}: marker = {t.marker}: expected an id in 0..{n_ids - 1} of the world's aruco_dict")
    if any(p.marker == t.marker for p in parts):
        raise ConfigError(f"{where}: marker = {t.marker}: a part carries it too; the tool needs an id of its own")
    return ToolMarker(int(t.marker), float(t.marker_mm), float(t.offset_mm))


def world_to_table(world: WorldConfig) -> dict[str, Any]:
    """The ``[world]`` table of ``world`` (what :func:`world_from_table` reads back to an equal config)."""
    out: dict[str, Any] = {k: getattr(world, k) for k in ("table_z_mm", "grip_tolerance_mm", "snap_mm",
                                                          "grip_tilt_deg", "aruco_dict")}
    parts = []
    for p in world.parts:
        if p.fed:
            continue  # the feeder's queue values bring them back
        d = dataclasses.asdict(p)
        del d["fed"]
        d["size_mm"] = list(p.size_mm) if p.shape == "box" else [p.size_mm[0], p.size_mm[2]]
        d["colour"] = list(p.colour)
        if p.marker is None:
            del d["marker"]
        parts.append(d)
    out["parts"] = parts
    for key in ("feeder", "pallet", "camera", "tool_marker"):
        value = getattr(world, key)
        if value is not None:
            out[key] = {k: v for k, v in dataclasses.asdict(value).items() if v is not None}
    return out


def load_world(path: str | Path) -> WorldConfig:
    """The world of a file: ``.json`` holds the table itself (:func:`world_to_table`), anything else is a TOML
    cell file whose ``[world]`` table is read. :class:`ConfigError` for a missing, unreadable or bad file, or a
    cell file without ``[world]``."""
    p = Path(path)
    if p.suffix == ".json":
        try:
            data = json.loads(p.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ConfigError(f"{p}: no such file") from None
        except OSError as exc:
            raise ConfigError(f"{p}: cannot read it: {exc.strerror or exc}") from None
        except (ValueError, UnicodeDecodeError) as exc:
            raise ConfigError(f"{p}: not valid JSON: {exc}") from None
        return world_from_table(data, f"{p}")
    from aioadept.cell.schema import load_toml

    data = load_toml(p)
    if "world" not in data:
        raise ConfigError(f"{p}: no [world] table")
    return world_from_table(data["world"], f"{p} [world]")


__all__ = ["ARUCO_DICTS", "load_world", "world_from_table", "world_to_table"]
