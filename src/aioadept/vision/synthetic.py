"""Synthetic views with known truth, for the part locator's and the calibration's tests and benchmarks.

It draws what a calibrated camera (:class:`aioadept.vision.calibration.CameraCalibration`, the same pinhole model as
the virtual and world cameras) sees of flat parts on the table and of ArUco markers at any pose (a marker on the
robot's tool for the calibration): every 3-D point goes through ``cv2.projectPoints``, markers are
``cv2.aruco.generateImageMarker`` images warped into place with ``cv2.warpPerspective`` (one white module of margin
around the marker, as printed labels have and as the world camera draws them), faces are ``cv2.fillConvexPoly``
polygons; then a Gaussian blur (the in-focus lens blur) and Gaussian sensor noise, mono8. Nothing here is a
detector: the locator must find everything again with OpenCV.

The world camera of the simulated cell (``aioadept.vision.world_camera``, on its own branch as this is written) renders the
world's parts the same way; this module stays small so that camera can reuse :func:`draw_marker` for a marker on
the tool.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aioadept.vision.calibration import CameraCalibration

TABLE_GREY = 198
"""The table top's grey level (the world camera's light grey table, (200, 200, 196) BGR, in mono8)."""


SUPERSAMPLE = 4
"""Markers are warped at this many times the image's resolution and box-averaged down."""


def aruco_bits(dictionary: str) -> int:
    """Data bits per side of an OpenCV ArUco dictionary name (``DICT_4X4_50`` -> 4)."""
    return int(dictionary.split("_")[1].split("X")[0])


def label_mm(marker_mm: float, dictionary: str) -> float:
    """Side of the white label a marker of side ``marker_mm`` (black border included) is printed on: one module
    of white margin on each side."""
    bits = aruco_bits(dictionary)
    return marker_mm * (bits + 4) / (bits + 2)


def flat_pose(x_mm: float, y_mm: float, z_mm: float, yaw_deg: float) -> np.ndarray:
    """4 x 4 frame lying flat at (x, y, z), turned ``yaw_deg`` about z."""
    a = math.radians(yaw_deg)
    m = np.eye(4)
    m[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    m[:3, 3] = (x_mm, y_mm, z_mm)
    return m


def grey_of(rgb: tuple[int, int, int]) -> int:
    """The mono8 grey level a colour (RGB) becomes, as ``cv2.cvtColor(..., COLOR_BGR2GRAY)`` computes it."""
    import cv2

    px = np.array([[[rgb[2], rgb[1], rgb[0]]]], np.uint8)
    return int(cv2.cvtColor(px, cv2.COLOR_BGR2GRAY)[0, 0])


@dataclass(frozen=True, slots=True)
class SyntheticPart:
    """A box lying flat on the table: centre (``x_mm``, ``y_mm``), turned ``yaw_deg``, ``size_mm`` = (length along
    its x, width, height); top face of colour ``rgb``; optional ArUco ``marker`` (id) of side ``marker_mm`` centred on
    top, the marker's x along the part's x (its image's top-left corner at (-s/2, +s/2))."""

    x_mm: float
    y_mm: float
    yaw_deg: float = 0.0
    size_mm: tuple[float, float, float] = (40.0, 30.0, 20.0)
    rgb: tuple[int, int, int] = (200, 40, 40)
    marker: int | None = None
    marker_mm: float = 15.0

    def frame(self, table_z_mm: float) -> np.ndarray:
        return flat_pose(self.x_mm, self.y_mm, table_z_mm, self.yaw_deg)


def _fill(img: np.ndarray, pts: np.ndarray, grey: int) -> None:
    import cv2

    hull = cv2.convexHull(pts.astype(np.float32))
    cv2.fillConvexPoly(img, np.round(hull * 16).astype(np.int32), int(grey), cv2.LINE_AA, 4)


def draw_marker(img: np.ndarray, cal: CameraCalibration, base_from_marker: np.ndarray, marker: int,
                marker_mm: float, dictionary: str = "DICT_4X4_50") -> None:
    """Draw ArUco ``marker`` on its white label into ``img`` (mono8, in place), the marker's frame at
    ``base_from_marker`` (its z out of the printed face). Nothing is drawn if the face turns away from the camera."""
    import cv2

    half = label_mm(marker_mm, dictionary) / 2
    corners = (base_from_marker @ np.array([[-half, half, 0, 1], [half, half, 0, 1], [half, -half, 0, 1],
                                            [-half, -half, 0, 1]]).T).T[:, :3]
    normal = base_from_marker[:3, 2]
    if float(normal @ (cal.base_from_camera[:3, 3] - base_from_marker[:3, 3])) <= 0:
        return  # seen from behind
    uv = cal.project(corners).astype(np.float32)
    side = float(np.linalg.norm(uv[1] - uv[0]))
    bits = aruco_bits(dictionary)
    module = max(2, int(math.ceil(SUPERSAMPLE * side / (bits + 4))))  # at least the supersampled resolution
    dic = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    inner = cv2.aruco.generateImageMarker(dic, marker, module * (bits + 2), borderBits=1)
    label = cv2.copyMakeBorder(inner, module, module, module, module, cv2.BORDER_CONSTANT, value=255)
    n = label.shape[0]
    src = np.float32([[-0.5, -0.5], [n - 0.5, -0.5], [n - 0.5, n - 0.5], [-0.5, n - 0.5]])
    h, w = img.shape[:2]
    x0, y0 = np.maximum(np.floor(uv.min(axis=0)).astype(int) - 2, 0)
    x1, y1 = np.minimum(np.ceil(uv.max(axis=0)).astype(int) + 2, [w, h])
    if x1 <= x0 or y1 <= y0:
        return
    # Warped at SUPERSAMPLE x the image's resolution, then box-averaged down (cv2.resize INTER_AREA): each image
    # pixel gets the label's area coverage, so edges land where the geometry puts them, to a small fraction of
    # a pixel (warping straight to the image's resolution aliases them by up to half a pixel).
    k = SUPERSAMPLE
    dst = (uv - np.float32([x0, y0]) + 0.5) * k - 0.5
    hom = cv2.getPerspectiveTransform(src, dst.astype(np.float32))
    size = (int(x1 - x0) * k, int(y1 - y0) * k)
    small = (int(x1 - x0), int(y1 - y0))
    warped = cv2.resize(cv2.warpPerspective(label, hom, size, flags=cv2.INTER_LINEAR).astype(np.float32), small,
                        interpolation=cv2.INTER_AREA)
    alpha = cv2.resize(cv2.warpPerspective(np.full_like(label, 255), hom, size, flags=cv2.INTER_LINEAR)
                       .astype(np.float32), small, interpolation=cv2.INTER_AREA) / 255
    roi = img[y0:y1, x0:x1].astype(np.float32)
    img[y0:y1, x0:x1] = np.round(roi * (1 - alpha) + warped * alpha).astype(np.uint8)


def render(cal: CameraCalibration, parts: Sequence[SyntheticPart] = (), *,
           markers: Sequence[tuple[np.ndarray, int, float]] = (), dictionary: str = "DICT_4X4_50",
           noise_sigma: float = 2.0, blur_sigma_px: float = 0.6, background: int = TABLE_GREY,
           seed: int | None = None) -> np.ndarray:
    """A mono8 view of ``parts`` on the table (``cal.table_z_mm``) and free ``markers`` (``(base_from_marker,
    id, marker_mm)``, e.g. one on the tool), as ``cal``'s camera sees them, with blur and noise. Parts are drawn
    farthest first; their sides in a darker shade (0.6) of their colour, as the world camera draws them."""
    import cv2

    img = np.full((cal.height_px, cal.width_px), background, np.uint8)
    cam = cal.base_from_camera[:3, 3]
    order = sorted(parts, key=lambda p: -float(np.linalg.norm(np.array([p.x_mm, p.y_mm, cal.table_z_mm]) - cam)))
    for part in order:
        m = part.frame(cal.table_z_mm)
        lx, ly, hz = part.size_mm[0] / 2, part.size_mm[1] / 2, part.size_mm[2]
        rect = np.array([[-lx, -ly], [lx, -ly], [lx, ly], [-lx, ly]])
        bottom = np.hstack([rect, np.zeros((4, 1)), np.ones((4, 1))])
        top = np.hstack([rect, np.full((4, 1), hz), np.ones((4, 1))])
        grey = grey_of(part.rgb)
        uv_b = cal.project((m @ bottom.T).T[:, :3])
        uv_t = cal.project((m @ top.T).T[:, :3])
        _fill(img, np.vstack([uv_b, uv_t]), round(grey * 0.6))
        _fill(img, uv_t, grey)
        if part.marker is not None:
            draw_marker(img, cal, m @ flat_pose(0, 0, hz, 0), part.marker, part.marker_mm, dictionary)
    for base_from_marker, marker, marker_mm in markers:
        draw_marker(img, cal, np.asarray(base_from_marker, float), marker, marker_mm, dictionary)
    if blur_sigma_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_sigma_px)
    if noise_sigma > 0:
        rng = np.random.default_rng(seed)
        img = np.clip(img + rng.normal(0.0, noise_sigma, img.shape), 0, 255).astype(np.uint8)
    return img


__all__ = ["TABLE_GREY", "SyntheticPart", "aruco_bits", "draw_marker", "flat_pose", "grey_of", "label_mm", "render"]
