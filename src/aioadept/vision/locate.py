"""The part locator: where the parts on the table are, in robot base coordinates, from one camera image.

An EPypes-style graph (:class:`aioadept.vision.graph.CompGraph`, like the sharpness graph) with two branches; all
image work is OpenCV's, the rest is the camera model (:class:`aioadept.vision.calibration.CameraCalibration`)::

    image ─ detect_markers ─ markers ─ marker_parts ──────────────┐
      │      (cv2.aruco.ArucoDetector, refined corners)        (cv2.solvePnP IPPE_SQUARE per marker)
      └──── segment_colours ─ colour_masks ─ colour_parts ─ ─ merge_parts ─ parts
             (cv2.inRange, cv2.morphologyEx)  (cv2.findContours; the contour's pixels back-projected to the
                                               top-face plane, then cv2.moments / cv2.minAreaRect in mm)

- **Marked parts:** each ArUco marker's pose in the camera by ``cv2.solvePnP`` (``SOLVEPNP_IPPE_SQUARE``, the
  solver for a square of known side) with the camera's intrinsics, then in the base frame by the calibration. Yaw
  is the marker's x axis about the base z axis. With a known top-face height (``height_mm`` above the table) the
  position is the point where the ray through the PnP centre meets that plane: PnP's direction to the marker is
  precise, its depth is not (a 0.1 px error on a 30 px marker is 3 mm of depth at 900 mm), and the plane fixes
  the depth. Without a height, PnP's own depth is used.
- **Unmarked coloured parts** (only when the request or the node's configuration names colours and a height: a
  wrong height shifts a part by height error x its distance from the optical axis / camera height, so the
  locator never guesses one): pixels within ``colour_tol`` grey levels (mono8) or per channel (BGR) of the
  colour, opened to remove noise; each outer contour's points are intersected with the plane of the top face, and
  the centre and yaw are those of that polygon in mm (``cv2.moments``, ``cv2.minAreaRect``), so perspective does not
  bias them. Yaw is along the longer side, in (-90, 90]; a square's is defined modulo 90.
- A colour blob that contains a marker is the same part: the marker's pose wins and takes the colour's name.

Every step is a pure function of its tokens (the calibration and hyperparameters are frozen tokens, overridable per
request); :func:`locate` runs the graph and turns a :class:`VisionError` into an error result.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from aioadept.bus.located import LocatedPart
from aioadept.errors import VisionError
from aioadept.vision.calibration import CameraCalibration, marker_in_camera
from aioadept.vision.graph import CompGraph

COLOURS: Mapping[str, tuple[int, int, int]] = {
    "red": (200, 40, 40), "green": (40, 160, 60), "blue": (40, 70, 200), "yellow": (230, 200, 40),
    "orange": (235, 130, 30), "white": (235, 235, 235), "grey": (128, 128, 128), "black": (30, 30, 30),
}
"""Colour names (RGB) the locator knows: the simulated world's (its cell file's ``colour`` names)."""


@dataclass(frozen=True, slots=True)
class Marker:
    """One detected ArUco marker: its id and its corners (4 x 2 px, cv2.aruco's order)."""

    id: int
    corners_px: np.ndarray


MIN_BLOB_PX = 20
"""Colour blobs of fewer pixels are dropped before any geometry (a part's top face covers hundreds)."""


# ------------------------------------------------------------------------------------------------------- steps
def detect_markers(image: np.ndarray, dictionary: str) -> tuple[Marker, ...]:
    """ArUco markers of ``dictionary`` (an OpenCV name, ``DICT_4X4_50``) in ``image`` (mono8 or BGR), with
    sub-pixel corners (contour fit; ``cv2.cornerSubPix`` too on markers with large modules)."""
    import cv2

    if not hasattr(cv2.aruco, dictionary) or not dictionary.startswith("DICT_"):
        raise VisionError(f"unknown ArUco dictionary {dictionary!r}")
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_CONTOUR
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)), params)
    corners, ids, _ = detector.detectMarkers(grey)
    if ids is None:
        return ()
    bits = int(dictionary.split("_")[1].split("X")[0])
    out = []
    for i, c in zip(ids.ravel(), corners, strict=True):
        c = c.reshape(4, 2).astype(np.float32)
        # Corner refinement, chosen by the marker's module (one data bit) in the image, as measured on synthetic
        # views with known corners: the contour fit (lines through the border's edge pixels) is the better one on
        # small markers (15 mm at 900 mm: 30 px, 5 px modules: yaw within 0.6 deg; CORNER_REFINE_SUBPIX's fixed
        # 5 px window reaches the inner bits there: up to 3 deg), but it turned larger tilted markers by ~0.45 deg
        # (0.7 px rms), where cv2.cornerSubPix with a window of 0.4 module gave 0.17 px rms.
        side = float(np.mean(np.linalg.norm(c - np.roll(c, 1, axis=0), axis=1)))
        module = side / (bits + 2)
        if module >= SUBPIX_MIN_MODULE_PX:
            win = int(min(0.4 * module, 10))
            c = cv2.cornerSubPix(grey, c.reshape(-1, 1, 2).copy(), (win, win), (-1, -1), _SUBPIX_CRITERIA)
        out.append(Marker(int(i), c.reshape(4, 2).astype(float)))
    return tuple(out)


SUBPIX_MIN_MODULE_PX = 8.0
"""Markers whose modules are at least this many pixels get ``cv2.cornerSubPix`` after the contour refinement."""
_SUBPIX_CRITERIA = (3, 50, 0.001)  # cv2.TERM_CRITERIA_EPS + TERM_CRITERIA_COUNT, 50 iterations, 0.001 px


def _yaw_deg(x_axis: np.ndarray) -> float:
    return math.degrees(math.atan2(float(x_axis[1]), float(x_axis[0])))


def marker_parts(markers: Sequence[Marker], calibration: CameraCalibration, marker_mm: float,
                 height_mm: float | None) -> tuple[LocatedPart, ...]:
    """Each marker's part in base coordinates (module docstring): PnP pose; its depth fixed by the top-face plane
    ``calibration.table_z_mm + height_mm`` when ``height_mm`` is known."""
    out = []
    base_from_cam = calibration.base_from_camera
    for m in markers:
        try:
            cam_from_marker = marker_in_camera(m.corners_px, calibration.K, calibration.dist_coeffs, marker_mm)
        except ValueError:
            continue
        base_from_marker = base_from_cam @ cam_from_marker
        centre, x_axis = base_from_marker[:3, 3], base_from_marker[:3, 0]
        if height_mm is not None:
            top = calibration.table_z_mm + height_mm
            try:
                c = calibration.on_plane(m.corners_px, top)
            except ValueError:
                pass
            else:
                # The corners on the plane: the centre of the square, and its x axis from both edges along x
                # (top-left -> top-right, bottom-left -> bottom-right). Measured on synthetic views, this yaw is
                # 5-10 x closer than PnP's rotation, whose tilt ambiguity on a 30 px marker leaks into the yaw.
                centre = c.mean(axis=0)
                x_axis = (c[1] - c[0]) + (c[2] - c[3])
        out.append(LocatedPart(float(centre[0]), float(centre[1]), float(centre[2]), _yaw_deg(x_axis), "marker",
                               m.id, corners_px=tuple(float(v) for v in m.corners_px.ravel())))
    return tuple(out)


def segment_colours(image: np.ndarray, colours: Mapping[str, tuple[int, int, int]] | Sequence[str],
                    colour_tol: int) -> dict[str, np.ndarray]:
    """One binary mask (0/255) per colour: the pixels within ``colour_tol`` of it (grey level of a mono8 image,
    each channel of a BGR one), opened with a 3 x 3 kernel so sensor noise leaves no specks. ``colours``: names of
    :data:`COLOURS` or a name -> RGB mapping."""
    import cv2

    table = colours if isinstance(colours, Mapping) else {}
    kernel = np.ones((3, 3), np.uint8)
    out = {}
    for name in colours:
        rgb = table.get(name) if table else COLOURS.get(name)
        if rgb is None:
            raise VisionError(f"unknown colour {name!r}; known: {', '.join(COLOURS)}")
        if image.ndim == 2:
            from aioadept.vision.synthetic import grey_of

            g = grey_of(tuple(rgb))
            lo, hi = np.array([max(0, g - colour_tol)]), np.array([min(255, g + colour_tol)])
        else:
            bgr = np.array([rgb[2], rgb[1], rgb[0]])
            lo, hi = np.clip(bgr - colour_tol, 0, 255), np.clip(bgr + colour_tol, 0, 255)
        mask = cv2.inRange(image, lo.astype(np.uint8), hi.astype(np.uint8))
        out[name] = cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)
    return out


def colour_parts(colour_masks: Mapping[str, np.ndarray], calibration: CameraCalibration, height_mm: float | None,
                 min_area_mm2: float, min_width_mm: float, min_fill: float) -> tuple[LocatedPart, ...]:
    """Each colour blob's part: its outer contour on the top-face plane, centre and yaw of that polygon (mm).

    Blobs smaller than ``min_area_mm2``, narrower than ``min_width_mm`` (a part's side seen in perspective is a
    thin strip) or filling less than ``min_fill`` of their rotated bounding box (an L of two sides) are not parts.
    """
    import cv2

    if not colour_masks:
        return ()
    if height_mm is None:
        raise VisionError("locating coloured parts needs the height of their top face: give height_mm")
    plane = calibration.table_z_mm + height_mm
    out = []
    for name, mask in colour_masks.items():
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        for c in contours:
            if cv2.contourArea(c) < MIN_BLOB_PX:  # specks: not worth back-projecting
                continue
            # The contour runs through the boundary pixels' centres, half a pixel inside the face's edge; the
            # centre is unaffected, the sides come out about a pixel short.
            pts = calibration.on_plane(c.reshape(-1, 2).astype(float), plane)[:, :2].astype(np.float32)
            mom = cv2.moments(pts)
            area = mom["m00"]
            if area < min_area_mm2:
                continue
            (_, _), (w, h), angle = cv2.minAreaRect(pts)
            if min(w, h) < min_width_mm or area < min_fill * w * h:
                continue
            cx, cy = mom["m10"] / area, mom["m01"] / area
            yaw = angle if w >= h else angle + 90.0  # along the longer side
            yaw = (yaw + 90.0) % 180.0 - 90.0
            if yaw <= -90.0:
                yaw += 180.0
            out.append(LocatedPart(float(cx), float(cy), plane, float(yaw), "colour", None, name,
                                   float(max(w, h)), float(min(w, h))))
    return tuple(out)


def merge_parts(marker_parts: Sequence[LocatedPart], colour_parts: Sequence[LocatedPart]) -> tuple[LocatedPart, ...]:
    """Marker parts first (sorted by id), then colour parts (by colour, then x, y); a colour blob holding a
    marker's centre is that marker's part, which takes the colour's name and the blob's size."""
    import dataclasses

    markers = sorted(marker_parts, key=lambda p: (p.marker if p.marker is not None else -1))
    rest = []
    for cp in colour_parts:
        hit = None
        for i, mp in enumerate(markers):
            if not mp.colour and math.hypot(mp.x_mm - cp.x_mm, mp.y_mm - cp.y_mm) < 0.5 * (cp.width_mm or 0.0):
                hit = i
                break
        if hit is None:
            rest.append(cp)
        else:
            markers[hit] = dataclasses.replace(markers[hit], colour=cp.colour, length_mm=cp.length_mm,
                                               width_mm=cp.width_mm)
    rest.sort(key=lambda p: (p.colour, round(p.x_mm, 1), round(p.y_mm, 1)))
    return (*markers, *rest)


# ------------------------------------------------------------------------------------------------------ the graph
DEFAULT_HYPERPARAMETERS: Mapping[str, Any] = {
    "dictionary": "DICT_4X4_50",
    "marker_mm": 15.0,
    "height_mm": None,
    "colours": (),
    "colour_tol": 12,
    "min_area_mm2": 100.0,
    "min_width_mm": 5.0,
    "min_fill": 0.8,
}
"""Frozen tokens of :func:`locate_graph` besides the calibration: the ArUco dictionary, the markers' side (black
border included, mm), the top faces' height above the table (None: unknown), the colours searched (names of
:data:`COLOURS`; none by default) and the blob filters. A request may override ``marker_mm``, ``height_mm`` and
``colours``."""


def locate_graph(calibration: CameraCalibration, **hyperparameters: Any) -> CompGraph:
    """The locator graph for a camera calibrated as ``calibration``. Free input ``image``; output ``parts`` (a
    tuple of :class:`~aioadept.bus.located.LocatedPart`)."""
    graph = CompGraph(
        func_dict={"detect_markers": detect_markers, "marker_parts": marker_parts,
                   "segment_colours": segment_colours, "colour_parts": colour_parts, "merge_parts": merge_parts},
        func_io={
            "detect_markers": (("image", "dictionary"), "markers"),
            "marker_parts": (("markers", "calibration", "marker_mm", "height_mm"), "found_markers"),
            "segment_colours": (("image", "colours", "colour_tol"), "colour_masks"),
            "colour_parts": (("colour_masks", "calibration", "height_mm", "min_area_mm2", "min_width_mm",
                              "min_fill"), "found_colours"),
            "merge_parts": (("found_markers", "found_colours"), "parts"),
        },
        frozen_tokens={**DEFAULT_HYPERPARAMETERS, "calibration": calibration},
        name="locate",
    )
    return graph.with_frozen(**hyperparameters) if hyperparameters else graph


@dataclass(frozen=True, slots=True)
class LocateResult:
    """Outcome of one locate run: the parts (or an ``error``), and the graph's time."""

    parts: tuple[LocatedPart, ...]
    error: str | None
    proc_time_ms: float
    node_time_ms: Mapping[str, float]

    @property
    def ok(self) -> bool:
        return self.error is None


def locate(image: np.ndarray, graph: CompGraph, **overrides: Any) -> LocateResult:
    """Run the locator ``graph`` on ``image`` (``overrides``: frozen tokens for this run); a :class:`VisionError`
    (unknown colour, no height for colours) becomes an error result. Other exceptions (bugs) propagate."""
    t0 = time.perf_counter()
    try:
        run = graph.run(image=image, **overrides)
    except VisionError as exc:
        return LocateResult((), str(exc), (time.perf_counter() - t0) * 1e3, {})
    return LocateResult(tuple(run["parts"]), None, run.total_time_s * 1e3,
                        {k: v * 1e3 for k, v in run.node_time_s.items()})


__all__ = ["COLOURS", "DEFAULT_HYPERPARAMETERS", "LocateResult", "Marker", "colour_parts", "detect_markers",
           "locate", "locate_graph", "marker_parts", "merge_parts", "segment_colours"]
