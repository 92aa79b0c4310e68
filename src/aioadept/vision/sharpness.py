"""Sharpness of the calibration object: the eight steps of the paper's Fig. 7 as pure functions, and the graph.

Data path (token names as in the paper)::

    image ─ highlight_light ─ thresholded_light ─ erosion ─ eroded ─ find_ccomp ─ ccomp
      ─ identify_object_region ─ object_region ─ crop_roi(image) ─ roi ─ sobel_x ─ sobelx_im
      ─ h_profile_sobelx ─ profile_sx ─ measure_sharpness ─ sharpness

The calibration object is a white plate with nested rectangles drawn as thin black lines, seen against a dark
background. Thresholding keeps the light plate; erosion removes speckles and thin bright bridges to clutter; among
the connected components the plate is the one whose bounding box has the expected width/height ratio and a minimum
area. The black lines split the plate's light area into nested rings when the image is sharp; the object's region is
the bounding box of the outermost ring, which is the whole plate either way. The Sobel x gradient of the cropped
plate responds to the vertical black lines; its middle row is the profile, and the standard deviation of the
profile is the sharpness: sharp lines give tall narrow gradient peaks, blurred lines low wide ones.

Every step takes numpy arrays (OpenCV's mono8 ``uint8`` images) and keyword-free hyperparameters, so the graph
can feed them as frozen tokens. When no region qualifies, :func:`identify_object_region` raises
:class:`aioadept.errors.ObjectNotFound` (a :class:`~aioadept.errors.VisionError`): the node turns it into an error
result (``error="no object found: ..."``), never NaN.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from aioadept.errors import ObjectNotFound, VisionError
from aioadept.vision.graph import CompGraph, GraphRun


@dataclass(frozen=True, slots=True, eq=False)
class Components:
    """Connected components (8-connected) of the non-zero pixels of a binary image, one row per component.

    ``stats`` is an ``(n, 5)`` int array of ``[x, y, width, height, area]`` in px: the bounding box and the area
    enclosed by the component's outer boundary (holes included, so a plate split into nested rings by sharp black
    lines keeps the plate's area). ``contours`` are the outer boundaries (OpenCV point arrays).
    """

    stats: np.ndarray
    contours: tuple[np.ndarray, ...]

    @property
    def count(self) -> int:
        return int(self.stats.shape[0])


@dataclass(frozen=True, slots=True)
class Region:
    """An axis-aligned region of an image in px: top-left ``x_px, y_px``, size, and pixel count of its component."""

    x_px: int
    y_px: int
    width_px: int
    height_px: int
    area_px: int = 0

    @property
    def aspect(self) -> float:
        """Width / height."""
        return self.width_px / self.height_px


# ------------------------------------------------------------------------------------------------------- steps
def highlight_light(image: np.ndarray, threshold: int) -> np.ndarray:
    """Binary mask (0/255 ``uint8``) of the pixels of a mono8 ``image`` brighter than ``threshold`` (0..255)."""
    if image.ndim != 2:
        raise VisionError(f"expected a mono8 image, got shape {image.shape}")
    _, out = cv2.threshold(image, threshold, 255, cv2.THRESH_BINARY)
    return out


def erosion(binary: np.ndarray, kernel_px: int, iterations: int) -> np.ndarray:
    """Erode a binary mask with a square ``kernel_px`` x ``kernel_px`` structuring element ``iterations`` times.

    Removes bright speckles (sensor noise, specular glints) and cuts thin bright bridges between the plate and
    clutter, so the plate's component keeps the plate's shape.
    """
    kernel = np.ones((kernel_px, kernel_px), np.uint8)
    return cv2.erode(binary, kernel, iterations=iterations)


def find_ccomp(binary: np.ndarray) -> Components:
    """Connected components (8-connected) of the non-zero pixels of ``binary``, with bounding boxes and areas.

    Traced as outer contours (``cv2.findContours``, ``RETR_EXTERNAL``): each outer boundary is one component. On a
    1024 x 768 mask this is about ten times faster than labelling every pixel with statistics, and the region
    filter needs only boxes and areas.
    """
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    stats = np.zeros((len(contours), 5), np.int64)
    for i, c in enumerate(contours):
        x, y, w, h = cv2.boundingRect(c)
        # A one-pixel-wide blob has zero enclosed area; count its pixels' extent instead so it is never 0 < 1.
        stats[i] = (x, y, w, h, max(int(cv2.contourArea(c)), 1))
    return Components(stats=stats, contours=tuple(contours))


def identify_object_region(ccomp: Components, wh_ratio_range: tuple[float, float], min_area_px: int) -> Region:
    """The component that looks like the calibration object: the bounding box with the largest area among those
    whose width/height ratio lies in ``wh_ratio_range`` (inclusive) and whose component has at least
    ``min_area_px`` px of enclosed area.

    Raises :class:`aioadept.errors.ObjectNotFound` when none qualifies (the message says how many were examined).
    """
    lo, hi = wh_ratio_range
    best: Region | None = None
    for row in ccomp.stats:
        x, y, w, h, area = (int(v) for v in row)
        if area < min_area_px or h == 0 or not (lo <= w / h <= hi):
            continue
        if best is None or w * h > best.width_px * best.height_px:
            best = Region(x, y, w, h, area)
    if best is None:
        raise ObjectNotFound(
            f"no object found: none of {ccomp.count} light regions has width/height in [{lo}, {hi}] "
            f"and area >= {min_area_px} px",
            attributes={"n_regions": ccomp.count})
    return best


def crop_roi(image: np.ndarray, region: Region, margin_px: int) -> np.ndarray:
    """The part of ``image`` inside ``region`` shrunk by ``margin_px`` on every side (a view, not a copy).

    The margin keeps the plate's own outer edge (bright plate against dark background, blurred into a ramp when out
    of focus) out of the measurement, so only the black lines count.
    """
    m = margin_px
    if region.width_px <= 2 * m + 2 or region.height_px <= 2 * m + 2:
        raise ObjectNotFound(f"no object found: region {region.width_px}x{region.height_px} px too small for "
                             f"a margin of {m} px")
    return image[region.y_px + m: region.y_px + region.height_px - m,
                 region.x_px + m: region.x_px + region.width_px - m]


def sobel_x(roi: np.ndarray, ksize: int) -> np.ndarray:
    """Horizontal Sobel derivative (``float32``) of ``roi``; ``ksize`` is the aperture (1, 3, 5 or 7)."""
    return cv2.Sobel(roi, cv2.CV_32F, 1, 0, ksize=ksize)


def h_profile_sobelx(sobelx_im: np.ndarray) -> np.ndarray:
    """The middle row (in y) of the gradient image: a 1-D profile across the vertical lines."""
    return sobelx_im[sobelx_im.shape[0] // 2, :]


def measure_sharpness(profile_sx: np.ndarray) -> float:
    """Sharpness: the standard deviation of the gradient profile (grey levels per px; larger is sharper)."""
    return float(np.std(profile_sx, dtype=np.float64))


# ------------------------------------------------------------------------------------------------------ the graph
DEFAULT_HYPERPARAMETERS: Mapping[str, Any] = {
    # Halfway between the dark background (~20) and the white plate (~230) of the virtual camera; the plate stays
    # above it even when defocus spreads the black lines.
    "threshold": 128,
    "erosion_kernel_px": 3,
    "erosion_iterations": 2,
    # The plate is 3:2 (1.5); a wide range tolerates rotation, perspective and partial erosion at the corners.
    "wh_ratio_range": (1.2, 1.9),
    "min_area_px": 20_000,
    "roi_margin_px": 12,
    "sobel_ksize": 3,
}
"""Frozen tokens of :func:`sharpness_graph` (the shaded ellipses of Fig. 7)."""


def sharpness_graph(**hyperparameters: Any) -> CompGraph:
    """The paper's sharpness graph (Fig. 7) with :data:`DEFAULT_HYPERPARAMETERS`, overridable by keyword.

    Free input token: ``image`` (mono8). Output token: ``sharpness`` (float). Unknown keywords raise
    :class:`aioadept.errors.GraphError`.
    """
    graph = CompGraph(
        func_dict={
            "highlight_light": highlight_light,
            "erosion": erosion,
            "find_ccomp": find_ccomp,
            "identify_object_region": identify_object_region,
            "crop_roi": crop_roi,
            "sobel_x": sobel_x,
            "h_profile_sobelx": h_profile_sobelx,
            "measure_sharpness": measure_sharpness,
        },
        func_io={
            "highlight_light": (("image", "threshold"), "thresholded_light"),
            "erosion": (("thresholded_light", "erosion_kernel_px", "erosion_iterations"), "eroded"),
            "find_ccomp": (("eroded",), "ccomp"),
            "identify_object_region": (("ccomp", "wh_ratio_range", "min_area_px"), "object_region"),
            "crop_roi": (("image", "object_region", "roi_margin_px"), "roi"),
            "sobel_x": (("roi", "sobel_ksize"), "sobelx_im"),
            "h_profile_sobelx": (("sobelx_im",), "profile_sx"),
            "measure_sharpness": (("profile_sx",), "sharpness"),
        },
        frozen_tokens=DEFAULT_HYPERPARAMETERS,
        name="sharpness",
    )
    return graph.with_frozen(**hyperparameters) if hyperparameters else graph


def frame_sharpness_graph(sobel_ksize: int = 3) -> CompGraph:
    """Sharpness of the whole frame, no object search: the same Sobel-x profile measure as :func:`sharpness_graph`
    on every pixel. For aiming and focusing a real camera at any scene (and for a camera's test pattern), where the
    calibration object may not be in view. Free input token ``image``; output ``sharpness``."""
    return CompGraph(
        func_dict={"sobel_x": sobel_x, "h_profile_sobelx": h_profile_sobelx, "measure_sharpness": measure_sharpness},
        func_io={
            "sobel_x": (("image", "sobel_ksize"), "sobelx_im"),
            "h_profile_sobelx": (("sobelx_im",), "profile_sx"),
            "measure_sharpness": (("profile_sx",), "sharpness"),
        },
        frozen_tokens={"sobel_ksize": sobel_ksize},
        name="frame-sharpness",
    )


@dataclass(frozen=True, slots=True)
class SharpnessResult:
    """Outcome of measuring one image: ``sharpness`` or ``error`` (exactly one is set), region and timing."""

    sharpness: float | None
    error: str | None
    region: Region | None
    proc_time_ms: float
    node_time_ms: Mapping[str, float]

    @property
    def ok(self) -> bool:
        return self.error is None


def measure(image: np.ndarray, graph: CompGraph | None = None) -> SharpnessResult:
    """Run ``graph`` (default :func:`sharpness_graph`) on ``image``; a :class:`VisionError` becomes an error result.

    Other exceptions (bugs) propagate.
    """
    g = graph if graph is not None else _default_graph()
    t0 = time.perf_counter()
    try:
        run: GraphRun = g.run(image=image)
    except VisionError as exc:
        return SharpnessResult(None, str(exc), None, (time.perf_counter() - t0) * 1e3, {})
    return SharpnessResult(
        sharpness=float(run["sharpness"]), error=None, region=run.tokens.get("object_region"),
        proc_time_ms=run.total_time_s * 1e3,
        node_time_ms={k: v * 1e3 for k, v in run.node_time_s.items()})


_DEFAULT: list[CompGraph] = []


def _default_graph() -> CompGraph:
    if not _DEFAULT:
        _DEFAULT.append(sharpness_graph())
    return _DEFAULT[0]
