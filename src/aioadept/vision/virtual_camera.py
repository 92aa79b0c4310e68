"""A virtual camera that sees the calibration object on the simulated robot's tool, with thin-lens defocus.

The camera model is one chain, robot state -> tool pose at the frame's time -> thin-lens blur -> sensor noise ->
exposure/readout timing, each step a few small functions that read the same optics and paper geometry.

Where it sits: the sim publishes :class:`aioadept.bus.messages.RobotState` at 100 Hz; a
:class:`RobotStateFollower` (one owned thread) keeps a short :class:`PoseHistory` of tool poses, each at its own time on
this clock;
:class:`VirtualCamera` renders a frame at ``time.time()`` from the pose interpolated at that time (once a state sample
at or after that time has arrived, so a frame taken just after the robot stopped never shows it mid-motion; or at
once from the newest sample when that one says the robot is at rest and is at most ``rest_hold_s`` old: opt-in,
see :data:`DEFAULT_REST_HOLD_S`), and the acquisition service buffers
the frames like those of a real camera.

Model:

- a pinhole camera fixed in the world (``camera_pose``: OpenCV axes, z along the optical axis, x right, y down),
  1024 x 768 px of 4.65 um (Prosilica GC1020), focal length 35 mm (the paper's Fujinon HF35HA-1B);
- the paper's calibration object (:class:`CalibrationTarget`): a white plate with nested rectangles drawn as thin
  black lines, on a dark background, fixed to the tool (``target_offset`` from the tool frame; default: centred on
  the tool origin, facing along the tool's +z);
- thin-lens defocus: the lens is focused at ``focus_distance_mm``; an object at distance u is imaged with a circle
  of confusion of diameter ``c = A * |v_u - v_s| / v_u`` on the sensor (``A = f / N`` the aperture, ``v`` the image
  distances ``f u / (u - f)``), rendered as a disk kernel, combined with a small in-focus blur of lens and sensor;
- additive Gaussian sensor noise, mono8.

:func:`paper_camera` builds the camera of the paper's experiment: it sits on the tool's +z axis in front of the
approach pose (:func:`paper_approach_pose`, where ``init_move`` leaves the robot), looking back at the tool, with
the focal plane ``focus_offset_mm`` (default 20 mm) ahead of the approach pose. Moving the tool along +z
(``MoveToolZ(+delta_z)``) brings the object closer; over a sweep the sharpness rises to one peak at the focal plane
and falls. With f/2.8 the circle of confusion grows by about 1.4 px per mm of defocus: a depth of field of about
3 mm (circle <= 2 px), so steps of 1.5-2.5 mm are resolved.

Rendering cost is bounded for >= 10 fps: the target texture is drawn once at the image scale of the focal plane,
each frame warps it (``cv2.warpPerspective``) into the bounding box of the projected plate only, blurs that box with
a disk kernel from a cache, and adds a window of a precomputed noise field at a random offset.
"""

from __future__ import annotations

import bisect
import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any
from dataclasses import dataclass

import cv2
import numpy as np

from aioadept.geometry import NULL, Pose, inverse_transform
from aioadept.robots import paper_cell
from aioadept.vision.sources import Camera, Frame

log = logging.getLogger(__name__)

# The paper's init_move, written once in aioadept.robots.paper_cell (these names are kept for old imports).
PAPER_HOME_JOINTS_DEG = paper_cell.HOME_JOINTS_DEG
PAPER_REL_JOINTS_DEG = paper_cell.REL_JOINTS_DEG
PAPER_REL_TOOL = paper_cell.REL_TOOL
PAPER_REL_JOINTS_2_DEG = paper_cell.REL_JOINTS_2_DEG


@dataclass(frozen=True, slots=True)
class LensOptics:
    """Camera and lens. Defaults: Prosilica GC1020 (1024 x 768, 4.65 um pixels) with a 35 mm lens at f/2.8.

    ``psf_floor_px`` is the blur diameter of lens and sensor at perfect focus (no real lens is a pinhole).
    """

    focal_length_mm: float = 35.0
    f_number: float = 2.8
    pixel_size_mm: float = 0.00465
    width_px: int = 1024
    height_px: int = 768
    psf_floor_px: float = 1.2

    @property
    def aperture_mm(self) -> float:
        return self.focal_length_mm / self.f_number

    def image_distance_mm(self, object_distance_mm: float) -> float:
        """Thin lens: distance behind the lens at which an object at ``object_distance_mm`` is in focus."""
        f = self.focal_length_mm
        if object_distance_mm <= f:
            return math.inf
        return f * object_distance_mm / (object_distance_mm - f)

    def coc_px(self, object_distance_mm: float, focus_distance_mm: float) -> float:
        """Diameter (px) of the circle of confusion of a point at ``object_distance_mm`` when the lens is focused
        at ``focus_distance_mm`` (both measured from the lens along the optical axis)."""
        v_obj = self.image_distance_mm(object_distance_mm)
        v_sensor = self.image_distance_mm(focus_distance_mm)
        if math.isinf(v_obj):
            return math.inf
        return self.aperture_mm * abs(v_obj - v_sensor) / v_obj / self.pixel_size_mm

    def blur_diameter_px(self, object_distance_mm: float, focus_distance_mm: float) -> float:
        """Total blur diameter: circle of confusion combined with the in-focus floor."""
        return math.hypot(self.coc_px(object_distance_mm, focus_distance_mm), self.psf_floor_px)


@dataclass(frozen=True, slots=True)
class CalibrationTarget:
    """The paper's calibration object (Fig. 6): a white plate ``width_mm`` x ``height_mm`` with ``n_rectangles``
    nested rectangles drawn as black lines ``line_width_mm`` wide, the outermost ``border_mm`` inside the plate's
    edge and each next one ``spacing_mm`` further in. Grey levels: ``white`` plate, ``ink`` lines."""

    width_mm: float = 21.0
    height_mm: float = 14.0
    n_rectangles: int = 4
    line_width_mm: float = 0.15
    border_mm: float = 2.0
    spacing_mm: float = 1.2
    white: int = 225
    ink: int = 30

    def __post_init__(self) -> None:
        inner = 2 * (self.border_mm + (self.n_rectangles - 1) * self.spacing_mm + self.line_width_mm)
        if inner >= min(self.width_mm, self.height_mm):
            raise ValueError("calibration target: the nested rectangles do not fit on the plate")

    def texture(self, px_per_mm: float) -> np.ndarray:
        """The plate as a mono8 image at ``px_per_mm``, drawn at 4x and area-averaged so thin lines keep their
        grey-level weight (anti-aliased)."""
        ss = 4
        s = px_per_mm * ss
        w, h = max(2, round(self.width_mm * s)), max(2, round(self.height_mm * s))
        img = np.full((h, w), self.white, np.uint8)
        lw = max(1, round(self.line_width_mm * s))
        for i in range(self.n_rectangles):
            inset = self.border_mm + i * self.spacing_mm
            x0, y0 = round(inset * s), round(inset * s)
            x1, y1 = w - 1 - x0, h - 1 - y0
            # Filled black rectangle, then white inside: a border exactly lw px wide on every side.
            img[y0:y1 + 1, x0:x1 + 1] = self.ink
            img[y0 + lw:y1 + 1 - lw, x0 + lw:x1 + 1 - lw] = self.white
        out_w, out_h = max(2, round(self.width_mm * px_per_mm)), max(2, round(self.height_mm * px_per_mm))
        return cv2.resize(img, (out_w, out_h), interpolation=cv2.INTER_AREA)


def disk_kernel(diameter_px: float) -> np.ndarray:
    """A normalised disk (pillbox) kernel of the given diameter, anti-aliased by 8x8 supersampling per pixel.

    Diameters below 1 px give the identity kernel.
    """
    if diameter_px <= 1.0:
        return np.ones((1, 1), np.float32)
    r = diameter_px / 2.0
    half = int(math.ceil(r - 0.5))
    n = 2 * half + 1
    ss = 8
    coords = (np.arange(n * ss) + 0.5) / ss - n / 2.0
    xx, yy = np.meshgrid(coords, coords)
    inside = (xx * xx + yy * yy <= r * r).astype(np.float32)
    k = inside.reshape(n, ss, n, ss).mean(axis=(1, 3))
    return (k / k.sum()).astype(np.float32)


class NoiseField:
    """Additive Gaussian sensor noise (``sigma`` grey levels) for ``height`` x ``width`` mono8 frames: one field,
    drawn once, a little larger than the frame; each frame adds a window of it at a random offset, so a frame
    costs an addition, not a draw (the virtual cameras' noise: :class:`VirtualCamera`, the world camera).
    Not thread-safe (the generator): callers hold their own lock."""

    PAD = 64

    def __init__(self, height: int, width: int, sigma: float, *, seed: int | None = None,
                 rng: np.random.Generator | None = None) -> None:
        self.height, self.width, self.sigma = int(height), int(width), float(sigma)
        self.rng = rng if rng is not None else np.random.default_rng(seed)
        self.field: np.ndarray | None = None
        if self.sigma > 0:
            shape = (self.height + self.PAD, self.width + self.PAD)
            self.field = np.round(self.rng.standard_normal(shape, dtype=np.float32) * self.sigma).astype(np.int16)

    def add(self, frame: np.ndarray) -> np.ndarray:
        """``frame`` (mono8, height x width) plus a window of the field, saturated to 0..255."""
        if self.field is None:
            return frame
        dy, dx = (int(v) for v in self.rng.integers(0, self.PAD, size=2))
        window = self.field[dy:dy + self.height, dx:dx + self.width]
        return cv2.add(frame, window, dtype=cv2.CV_8U)


def _mix(weighted: Sequence[tuple[float, np.ndarray]]) -> np.ndarray:
    """Weighted sum of centred square kernels of odd sizes (each padded to the largest)."""
    n = max(k.shape[0] for _, k in weighted)
    out = np.zeros((n, n), np.float32)
    for w, k in weighted:
        m = (n - k.shape[0]) // 2
        out[m:m + k.shape[0], m:m + k.shape[0]] += np.float32(w) * k
    return out


# ------------------------------------------------------------------------------------------ paper geometry
def paper_approach_pose(forward: Callable[[Sequence[float]], Pose] | None = None) -> Pose:
    """The approach pose of the paper's focus application: where ``init_move`` leaves the robot.

    The motions of :mod:`aioadept.robots.paper_cell` (``MoveJoints([0,-90,180,0,90,0]); MoveRelJoints(...);
    MoveRelTool(...); MoveRelJoints(...)``), computed with the Viper s850 kinematics (``aioadept.robots.viper_s850``): forward
    kinematics of the joints after the first two moves, the tool-frame move, inverse kinematics for its joints,
    and forward kinematics again after the J6 increment. ``forward`` may replace the sim's forward function (the
    inverse then becomes a tool-frame composition, which is what a J6 rotation is for a flange on the J6 axis).
    """
    from aioadept.robots import viper_s850 as kin

    fk = forward or kin.forward
    joints = [h + d for h, d in zip(PAPER_HOME_JOINTS_DEG, PAPER_REL_JOINTS_DEG, strict=True)]
    after_tool = fk(joints) @ Pose.from_seq(PAPER_REL_TOOL)
    if forward is None:
        j = kin.inverse(after_tool, joints)
        return kin.forward([a + d for a, d in zip(j, PAPER_REL_JOINTS_2_DEG, strict=True)])
    return after_tool @ Pose(roll=PAPER_REL_JOINTS_2_DEG[5])


def camera_facing_tool(tool_pose: Pose, distance_mm: float) -> Pose:
    """Pose of a camera on the tool's +z axis ``distance_mm`` ahead of ``tool_pose``, looking back at the tool.

    Camera axes (OpenCV): z = -tool z (towards the tool), x = -tool x, y = tool y.
    """
    return tool_pose @ Pose(z=distance_mm, pitch=180.0)


# ------------------------------------------------------------------------------------------ the camera
DEFAULT_EXPOSURE_MS = 5.0
"""Exposure of the virtual camera: a typical short machine-vision exposure under good light."""
GIGE_BITS_PER_S = 1e9
"""GigE Vision link rate the readout time is derived from."""


def gige_readout_ms(frame_bytes: int, bits_per_s: float = GIGE_BITS_PER_S) -> float:
    """Time to move a frame over the link: ``frame_bytes * 8 / bits_per_s`` (6.29 ms for 1024x768 mono8)."""
    return frame_bytes * 8 / bits_per_s * 1e3

_DIRECT_BLUR_PX = 16.0
"""Blur diameters up to this are filtered at full resolution; larger ones on a shrunk copy (bounded cost)."""


class VirtualCamera(Camera):
    """Renders the calibration object on the robot's tool as a mono8 frame (see the module docstring).

    ``pose_source(t_s)`` returns the tool pose at epoch time ``t_s`` or ``None`` when unknown (no robot state yet;
    the frame then shows the empty background). :meth:`render` takes a pose directly (tests, figures).
    ``seed`` makes the noise reproducible. ``max_blur_px`` caps the blur diameter: far from focus (the robot on its
    way to the approach pose) the target is a smear anyway, and the cap bounds the rendering time.
    ``state_age(t_s)``, if given, is asked after the pose for the age of the robot state behind it
    (:meth:`RobotStateFollower.state_age_s`) and stamped on the frame as ``pose_age_s``: the node refuses to
    answer from a frame whose pose is older than its limit (a silent state stream means a frozen, maybe wrong pose).
    ``pose_guess(t_s)``, if given, is a pose that needs no wait (:meth:`RobotStateFollower.pose_if_at_rest`): the
    frame is rendered from it at once, while ``pose_source`` waits for the sample covering the exposure; the frame
    is kept only if that pose is the same (:func:`same_pose`), else rendered again. So the wait overlaps rendering
    and the modelled readout, and the frame is exactly the one ``pose_source`` alone would give.
    """

    def __init__(self, pose_source: Callable[[float], Pose | None] | None = None, *, camera_pose: Pose,
                 focus_distance_mm: float, optics: LensOptics = LensOptics(),
                 target: CalibrationTarget = CalibrationTarget(), target_offset: Pose = NULL,
                 noise_sigma: float = 2.0, background: int = 18, seed: int | None = None,
                 max_blur_px: float = 48.0, camera_id: str = "virtual",
                 clock: Callable[[], float] = time.time,
                 state_age: Callable[[float], float] | None = None, exposure_ms: float = DEFAULT_EXPOSURE_MS,
                 readout_ms: float | None = None, sleep: Callable[[float], None] | None = time.sleep,
                 pose_guess: Callable[[float], Pose | None] | None = None) -> None:
        if not (0 <= exposure_ms < math.inf) or (readout_ms is not None and not (0 <= readout_ms < math.inf)):
            raise ValueError(f"exposure_ms and readout_ms must be finite and >= 0, got {exposure_ms!r}, "
                             f"{readout_ms!r}")
        self.camera_id = camera_id
        self.exposure_ms = float(exposure_ms)
        self.readout_ms = float(readout_ms) if readout_ms is not None else \
            gige_readout_ms(optics.width_px * optics.height_px)
        self._sleep = sleep
        self._state_age = state_age
        self.max_blur_px = float(max_blur_px)
        self.camera_pose = camera_pose
        self.focus_distance_mm = float(focus_distance_mm)
        self.optics = optics
        self.target = target
        self.target_offset = target_offset
        self.noise_sigma = float(noise_sigma)
        self.background = int(background)
        self._pose_source = pose_source
        self._pose_guess = pose_guess
        self.guesses = 0  # frames rendered ahead from pose_guess (kept or re-rendered)
        self.rerenders = 0  # of those, rendered again because the covering pose differed
        self._clock = clock
        self._seq = 0
        self._world_to_cam = inverse_transform(camera_pose.to_matrix())
        # The sensor sits where the focal plane is imaged: that image distance sets the pinhole focal length.
        v = optics.image_distance_mm(self.focus_distance_mm)
        self._f_px = v / optics.pixel_size_mm
        self._k = np.array([[self._f_px, 0.0, optics.width_px / 2.0], [0.0, self._f_px, optics.height_px / 2.0],
                            [0.0, 0.0, 1.0]])
        self._tex_px_per_mm = self._f_px / self.focus_distance_mm
        self._texture = target.texture(self._tex_px_per_mm)
        th, tw = self._texture.shape
        w2, h2 = target.width_mm / 2.0, target.height_mm / 2.0
        # Texture corners (px) and the same corners on the plate in the target frame (mm, plate in z = 0).
        self._tex_corners = np.array([[0, 0], [tw, 0], [tw, th], [0, th]], np.float32)
        self._obj_corners = np.array([[-w2, -h2, 0, 1], [w2, -h2, 0, 1], [w2, h2, 0, 1], [-w2, h2, 0, 1]]).T
        self._kernels: dict[int, np.ndarray] = {}
        rng = np.random.default_rng(seed)
        self._rng = rng
        self._noise = NoiseField(optics.height_px, optics.width_px, self.noise_sigma, rng=rng)
        self._lock = threading.Lock()

    # --------------------------------------------------------------------------------------- geometry
    def target_in_camera(self, tool_pose: Pose) -> np.ndarray:
        """4x4 transform of the target frame in the camera frame (mm)."""
        return self._world_to_cam @ tool_pose.to_matrix() @ self.target_offset.to_matrix()

    def object_distance_mm(self, tool_pose: Pose) -> float:
        """Depth of the target's centre along the optical axis (mm)."""
        return float(self.target_in_camera(tool_pose)[2, 3])

    def blur_diameter_px(self, tool_pose: Pose) -> float:
        """Blur diameter (px) at which the target is rendered for ``tool_pose``."""
        return self.optics.blur_diameter_px(self.object_distance_mm(tool_pose), self.focus_distance_mm)

    def project(self, tool_pose: Pose) -> np.ndarray | None:
        """Image corners (4 x 2 px) of the plate, or None when any corner is not in front of the lens."""
        pts = self.target_in_camera(tool_pose) @ self._obj_corners
        z = pts[2]
        if np.any(z <= self.optics.focal_length_mm):
            return None
        uv = (self._k @ (pts[:3] / z))[:2].T
        return uv.astype(np.float32)

    # --------------------------------------------------------------------------------------- rendering
    def _disk(self, key: int) -> np.ndarray:
        k = self._kernels.get(key)
        if k is None:
            if len(self._kernels) > 256:
                self._kernels.clear()
            k = self._kernels[key] = disk_kernel(key / 4.0)
        return k

    def _kernel(self, diameter_px: float) -> np.ndarray:
        """The disk kernel of ``diameter_px``: the two cached quarter-pixel disks around it, blended linearly. The
        blend keeps the rendered image (and so the sharpness) a continuous function of the pose: a kernel rounded to
        the nearest quarter pixel made the sharpness a staircase in z (steps of ~4 % every 0.2 mm near focus),
        which a sub-step fit of the sweep (apps/sweep.py) would read as structure."""
        x = diameter_px * 4.0
        lo = int(math.floor(x))
        f = x - lo
        k0 = self._disk(lo)
        if f < 1e-3:
            return k0
        return _mix([(1.0 - f, k0), (f, self._disk(lo + 1))])

    def _exposure_kernel(self, diameters_px: Sequence[float]) -> np.ndarray:
        """The mean of the disk kernels of ``diameters_px`` (the blur at instants spread evenly over one exposure):
        a target moving along the optical axis during the exposure integrates all those defocus blurs."""
        if len(diameters_px) == 1:
            return self._kernel(diameters_px[0])
        w = 1.0 / len(diameters_px)
        return _mix([(w, self._kernel(d)) for d in diameters_px])

    def _blur(self, roi: np.ndarray, diameter_px: float | Sequence[float]) -> np.ndarray:
        """Disk blur of ``roi`` (several diameters: their mean kernel, :meth:`_exposure_kernel`). Beyond
        :data:`_DIRECT_BLUR_PX` it blurs a proportionally shrunk copy and scales it back: the result is smooth at
        that scale anyway, and the cost stays that of a small kernel."""
        ds = [float(diameter_px)] if isinstance(diameter_px, (int, float)) else [float(d) for d in diameter_px]
        top = max(ds)
        if top <= _DIRECT_BLUR_PX:
            k = self._exposure_kernel(ds)
            return roi if k.shape[0] == 1 else cv2.filter2D(roi, -1, k, borderType=cv2.BORDER_REPLICATE)
        f = _DIRECT_BLUR_PX / top
        h, w = roi.shape
        small = cv2.resize(roi, (max(1, round(w * f)), max(1, round(h * f))), interpolation=cv2.INTER_AREA)
        small = cv2.filter2D(small, -1, self._exposure_kernel([d * f for d in ds]), borderType=cv2.BORDER_REPLICATE)
        return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)

    def render(self, tool_pose: Pose | None, *, exposure_poses: Sequence[Pose] = ()) -> np.ndarray:
        """A mono8 frame of the target at ``tool_pose`` (None: background only), with blur and noise.

        ``exposure_poses``: the tool's poses at instants spread evenly over the exposure (``tool_pose`` is the
        mid-exposure one); the target is blurred by the mean of their defocus kernels, the motion blur of a move
        along the optical axis (the focus sweep's). Its image position and size are those of ``tool_pose``: the
        sideways smear and the magnification change during the exposure are not modelled (a few tenths of a pixel
        for a sweep along the axis)."""
        o = self.optics
        frame = np.full((o.height_px, o.width_px), self.background, np.uint8)
        corners = self.project(tool_pose) if tool_pose is not None else None
        if corners is not None:
            diameters = [min(self.blur_diameter_px(p), self.max_blur_px) for p in (exposure_poses or (tool_pose,))]
            diameter = max(diameters)
            pad = int(math.ceil(diameter / 2)) + 2
            x0 = max(0, int(math.floor(corners[:, 0].min())) - pad)
            y0 = max(0, int(math.floor(corners[:, 1].min())) - pad)
            x1 = min(o.width_px, int(math.ceil(corners[:, 0].max())) + pad + 1)
            y1 = min(o.height_px, int(math.ceil(corners[:, 1].max())) + pad + 1)
            if x1 > x0 and y1 > y0:
                h = cv2.getPerspectiveTransform(self._tex_corners, corners - np.float32([x0, y0]))
                roi = cv2.warpPerspective(self._texture, h, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR,
                                          borderMode=cv2.BORDER_CONSTANT, borderValue=self.background)
                frame[y0:y1, x0:x1] = self._blur(roi, diameters)
        with self._lock:  # the Generator is not thread-safe
            return self._noise.add(frame)

    can_trigger = True

    def grab(self) -> Frame:
        """Expose now (``t_s``) for ``exposure_ms``, showing the pose at the exposure's mid-time, and deliver the
        frame no earlier than a real camera would: after the exposure and the readout (``sleep``; None renders
        without waiting, for tests and figures)."""
        t_s = self._clock()
        exposure_s, readout_s = self.exposure_ms / 1e3, self.readout_ms / 1e3
        t_mid = t_s + exposure_s / 2.0
        guess = self._pose_guess(t_mid) if self._pose_guess is not None else None
        image = None
        if guess is not None:
            # Render now from the at-rest pose; the covering sample decides below whether this frame stands.
            self.guesses += 1
            image = self.render(guess)
        pose = self._pose_source(t_mid) if self._pose_source is not None else None
        # Asked after pose_source, which may have waited for a sample covering t_mid.
        age = self._state_age(t_mid) if self._state_age is not None else None
        # A guess the covering pose confirms means the tool stood still from the at-rest sample (before the
        # exposure) to mid-exposure: no motion blur, and no further pose to ask for.
        confirmed = guess is not None and same_pose(pose, guess)
        exposure_poses = () if confirmed else self._exposure_poses(t_s, exposure_s, pose, age)
        if image is None or not same_pose(pose, guess) or exposure_poses:
            if image is not None:
                self.rerenders += 1  # the robot moved after the at-rest sample: never keep that frame
            image = self.render(pose, exposure_poses=exposure_poses)
        if self._sleep is not None:
            left = t_s + exposure_s + readout_s - self._clock()
            if left > 0:
                self._sleep(left)  # the physical exposure + readout time, not a readiness wait
        frame = Frame(image, t_s, self.camera_id, self._seq, age, exposure_s, readout_s)
        self._seq += 1
        return frame

    EXPOSURE_SAMPLES = 5
    """Poses per exposure when the tool moves during it (motion blur): the travel is sampled every fifth of the
    exposure, 0.14 mm at the focus sweep's 140 mm/s and 5 ms, a twentieth of the depth of field."""

    def _exposure_poses(self, t_s: float, exposure_s: float, mid: Pose | None,
                        age: float | None) -> tuple[Pose, ...]:
        """The poses spread over the exposure when the tool moved during it, else ``()`` (a still frame).

        The first half of the exposure is covered by the samples the mid-exposure pose waited for; the second half
        is extrapolated from it at the same rate (``mid + (mid - start)``), so no further wait for a later sample
        delays the frame: exact at constant speed, and within a few micrometres on the sweep's 0.1 s ramps. Not
        while the state stream is stale (``age`` > 0): a frozen pose has no motion to blur."""
        if self._pose_source is None or mid is None or exposure_s <= 0 or (age is not None and age > 0):
            return ()
        start = self._pose_source(t_s)
        if start is None or same_pose(start, mid):
            return ()
        m0, m1 = start.to_matrix(), mid.to_matrix()
        end = m1 @ inverse_transform(m0) @ m1  # as far beyond mid as start is before it (same motion)
        n = self.EXPOSURE_SAMPLES
        return tuple(Pose.from_matrix(_interpolate(m0, end, (k + 0.5) / n)) for k in range(n))


SAME_POSE_MM = 1e-6
"""Largest position difference (mm), and rotation-matrix entry difference, at which two poses render the same
frame in :meth:`VirtualCamera.grab` (interpolating between two equal at-rest samples changes the last bits only)."""


def same_pose(a: Pose | None, b: Pose | None) -> bool:
    """Whether ``a`` and ``b`` are the same pose up to rounding (:data:`SAME_POSE_MM`); two Nones are the same."""
    if a is None or b is None:
        return a is b
    ma, mb = a.to_matrix(), b.to_matrix()
    return bool(np.all(np.abs(ma[:3, 3] - mb[:3, 3]) <= SAME_POSE_MM)
                and np.all(np.abs(ma[:3, :3] - mb[:3, :3]) <= SAME_POSE_MM * 1e-3))


def paper_camera(pose_source: Callable[[float], Pose | None] | None = None, *, focus_offset_mm: float = 20.0,
                 working_distance_mm: float = 300.0, approach_pose: Pose | None = None,
                 **options) -> VirtualCamera:
    """The virtual camera of the paper's experiment (see the module docstring).

    ``working_distance_mm``: from the lens to the target at the approach pose; ``focus_offset_mm``: how far along
    the tool's +z from the approach pose the focal plane lies (so ``focus_offset_mm / delta_z`` steps of the focus
    application reach it). Other keywords go to :class:`VirtualCamera`.
    """
    appr = approach_pose if approach_pose is not None else paper_approach_pose()
    return VirtualCamera(pose_source, camera_pose=camera_facing_tool(appr, working_distance_mm),
                         focus_distance_mm=working_distance_mm - focus_offset_mm, **options)


# ------------------------------------------------------------------------------------------ pose history
class PoseHistory:
    """A short, thread-safe history of timestamped tool poses with interpolation at any time.

    ``add(t_s, pose, in_motion)`` appends (times must not decrease; an older sample is dropped; ``in_motion``
    defaults to True, the cautious guess). ``at(t_s)`` interpolates the
    position linearly and the rotation by spherical linear interpolation between the two samples around ``t_s``;
    before the first / after the last sample it returns the first / last pose (the robot is assumed still).
    Samples older than ``max_age_s`` behind the newest are discarded.
    """

    def __init__(self, *, max_age_s: float = 2.0, max_len: int = 2000) -> None:
        self.max_age_s = max_age_s
        self._t: deque[float] = deque(maxlen=max_len)
        self._m: deque[np.ndarray] = deque(maxlen=max_len)
        self._newest_in_motion = True
        self._lock = threading.Condition()

    def __len__(self) -> int:
        return len(self._t)

    def newest_t(self) -> float | None:
        """Time stamp of the newest sample, or None when there is none."""
        with self._lock:
            return self._t[-1] if self._t else None

    def newest_at_rest(self) -> float | None:
        """Time stamp of the newest sample if that sample says the robot is at rest (not in motion), else None."""
        with self._lock:
            return self._t[-1] if self._t and not self._newest_in_motion else None

    def add(self, t_s: float, pose: Pose, in_motion: bool = True) -> None:
        m = pose.to_matrix()
        with self._lock:
            if self._t and t_s < self._t[-1]:
                return
            self._t.append(t_s)
            self._m.append(m)
            self._newest_in_motion = bool(in_motion)
            while self._t and self._t[0] < t_s - self.max_age_s and len(self._t) > 2:
                self._t.popleft()
                self._m.popleft()
            self._lock.notify_all()

    def wait_covering(self, t_s: float, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` until a sample at or after ``t_s`` exists; True if one does.

        A camera exposing at ``t_s`` waits for this before rendering, so the pose comes from samples on both sides
        of ``t_s`` instead of the last one before it (which can be up to one state period stale: mid-motion).
        """
        deadline = time.monotonic() + timeout_s
        with self._lock:
            while not self._t or self._t[-1] < t_s:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._lock.wait(remaining)
            return True

    def at(self, t_s: float) -> Pose | None:
        with self._lock:
            if not self._t:
                return None
            times = list(self._t)
            i = bisect.bisect_right(times, t_s)
            if i == 0:
                m = self._m[0]
            elif i == len(times):
                m = self._m[-1]
            else:
                t0, t1 = times[i - 1], times[i]
                m0, m1 = self._m[i - 1], self._m[i]
                a = 0.0 if t1 == t0 else (t_s - t0) / (t1 - t0)
                m = _interpolate(m0, m1, a)
        return Pose.from_matrix(m)


def _interpolate(m0: np.ndarray, m1: np.ndarray, a: float) -> np.ndarray:
    """Rigid transform a fraction ``a`` of the way from ``m0`` to ``m1``: position linearly, rotation along the
    geodesic (slerp), via the axis-angle vector of the relative rotation (``cv2.Rodrigues``; no scipy import on the
    frame path)."""
    out = np.eye(4)
    out[:3, 3] = (1 - a) * m0[:3, 3] + a * m1[:3, 3]
    rvec, _ = cv2.Rodrigues(m0[:3, :3].T @ m1[:3, :3])
    step, _ = cv2.Rodrigues(rvec * a)
    out[:3, :3] = m0[:3, :3] @ step
    return out


DEFAULT_REST_HOLD_S = 0.0
"""How long after an at-rest state sample :meth:`RobotStateFollower.pose_at` holds its pose without waiting for
the next sample. Off (0) by default: an at-rest sample from *before* a motion looks the same as one from its end,
so a motion shorter than the hold (``--time-scale 10``: a 2 mm step takes less than one 100 Hz period) would be
rendered at its start pose (measured: the sharpness of the previous step, test_vision_with_sim). Opt in (e.g.
0.015) only where every motion lasts longer than the hold."""


class TopicFollower:
    """One owned non-daemon thread following one topic of the bus with a
    :class:`aioadept.bus.pubsub.SyncSubscriber` (connects unless ``@addr``; CURVE if the stream uses it).
    :meth:`start` connects (raising the subscriber's error), :meth:`stop` joins the thread; also a context manager.
    Subclasses give ``WHAT`` (for the log), :meth:`decode` (payload -> value) and :meth:`take` (value, receipt
    time on ``clock``); a message that does not decode is logged and skipped, never fatal."""

    WHAT = "state"

    def __init__(self, endpoint: str, topic: bytes, *, curve: Any = None,
                 clock: Callable[[], float] = time.time) -> None:
        self.endpoint = endpoint
        self.topic = topic
        self.curve = curve
        self.received = 0
        self._clock = clock
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None

    def decode(self, payload: bytes) -> Any:
        raise NotImplementedError

    def take(self, value: Any, t_s: float) -> None:
        raise NotImplementedError

    def start(self):  # noqa: ANN201 - the subclass
        if self._thread is not None:
            raise RuntimeError(f"{type(self).__name__} already started")
        self._thread = threading.Thread(target=self._run, name=f"{self.WHAT.replace(' ', '-')}:{self.endpoint}")
        self._thread.start()
        self._ready.wait(5.0)
        if self._error is not None:
            raise self._error
        return self

    def _run(self) -> None:
        from aioadept.bus.pubsub import SyncSubscriber
        from aioadept.errors import BusError

        try:
            sub = SyncSubscriber(self.endpoint, topics=(self.topic,), curve=self.curve)
        except BusError as exc:
            self._error = exc
            self._ready.set()
            return
        self._ready.set()
        with sub:
            while not self._stop.is_set():
                try:
                    message = sub.recv(timeout_s=0.1)  # wake up regularly to see the stop flag
                except BusError as exc:
                    if exc.__cause__ is not None:  # the socket itself failed (ZeroMQ error): stop following
                        log.error("%s: %s", self.WHAT, exc)
                        break
                    log.warning("%s: %s", self.WHAT, exc)  # a message of three frames: not ours, keep following
                    continue
                if message is None:
                    continue
                t_s = self._clock()
                topic, payload = message
                if not topic:  # a single frame carries the topic as a prefix
                    payload = payload[len(self.topic):]
                try:
                    value = self.decode(payload)
                except Exception as exc:  # a bad sample must not kill the camera
                    log.warning("%s: undecodable message (%s)", self.WHAT, exc)
                    continue
                self.take(value, t_s)
                self.received += 1

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def __enter__(self):  # noqa: ANN204
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


class RobotStateFollower(TopicFollower):
    """Subscribes to the sim's robot state stream and fills a :class:`PoseHistory` (samples at their own time).

    One owned non-daemon thread reading a :class:`aioadept.bus.pubsub.SyncSubscriber`. :meth:`start` connects,
    :meth:`stop` sets the stop flag, joins the thread and closes the socket; also a context manager. Samples are
    stamped on the frame clock (``time.time()``): the state's own ``wall_time_s``, shifted back only when samples
    arrive before they were taken (the sim's clock ahead of ours), so a sample delayed on its way is still placed
    at its own time and the stamp is never later than the receipt.
    """

    def __init__(self, endpoint: str, *, history: PoseHistory | None = None, topic: bytes = b"robot.state",
                 max_wait_s: float = 0.05, clock: Callable[[], float] = time.time, curve: Any = None,
                 rest_hold_s: float = DEFAULT_REST_HOLD_S) -> None:
        if not 0 <= rest_hold_s < math.inf:
            raise ValueError(f"rest_hold_s must be finite and >= 0, got {rest_hold_s!r}")
        super().__init__(endpoint, topic, curve=curve, clock=clock)  # curve: the sim's stream may use CURVE
        self.rest_hold_s = float(rest_hold_s)
        self.max_wait_s = max_wait_s
        self.history = history if history is not None else PoseHistory()
        self.min_delay_s: float | None = None
        """Smallest receipt time minus the sample's ``wall_time_s`` seen so far (see :meth:`_run`)."""
        self.rest_holds = 0  # poses held from an at-rest sample without waiting (pose_at)
        self.last_state = None

    WHAT = "robot state"

    def decode(self, payload: bytes) -> Any:
        from aioadept.bus.messages import RobotState

        return RobotState.from_bytes(payload)

    def take(self, state: Any, t_s: float) -> None:
        # The sample's own time on our clock: its wall time, shifted only if our clock is behind the sim's
        # (a sample received before it was taken), by the largest such lead seen: the offset nearest 0 that
        # the traffic allows (aioadept.apps.sweep_model.clock_offset; the focus sweep maps the samples by
        # the same rule). Stamping on receipt instead made the shown pose lag the robot by each sample's
        # own delay, up to a millisecond when this process is busy rendering: 0.2 mm at a focus sweep's
        # 200 mm/s. Never later than the receipt.
        delay = t_s - state.wall_time_s
        if self.min_delay_s is None or delay < self.min_delay_s:
            self.min_delay_s = delay
        self.history.add(state.wall_time_s + min(0.0, self.min_delay_s), state.pose, state.in_motion)
        self.last_state = state

    def pose_at(self, t_s: float) -> Pose | None:
        """The tool pose at epoch ``t_s``: waits (up to ``max_wait_s``) for a state sample received at or after
        ``t_s``, then interpolates; without any sample yet, None at once; if the stream stalls, the last pose.

        With ``rest_hold_s > 0`` (opt-in, :data:`DEFAULT_REST_HOLD_S` says why it is off): no wait when the newest
        sample says the robot is **at rest** and was received at most ``rest_hold_s`` before ``t_s``; the pose is
        held from it. A sample in motion, or an older one (a stream that stalls), still waits; the node's
        stale-state check (``max_state_age_s``) is unchanged."""
        rest_t = self.history.newest_at_rest()
        if rest_t is not None and self.rest_hold_s > 0 and rest_t <= t_s <= rest_t + self.rest_hold_s:
            self.rest_holds += 1
            return self.history.at(t_s)
        if len(self.history):
            self.history.wait_covering(t_s, self.max_wait_s)
        return self.history.at(t_s)

    def pose_if_at_rest(self, t_s: float) -> Pose | None:
        """The newest sample's pose, at once, if that sample says the robot is at rest and was received at or
        before ``t_s``; else None. A guess only (:class:`VirtualCamera` ``pose_guess``): a motion may have started
        since, so the camera checks it against :meth:`pose_at` before keeping the frame."""
        rest_t = self.history.newest_at_rest()
        if rest_t is None or rest_t > t_s:
            return None
        return self.history.at(t_s)

    def state_age_s(self, t_s: float | None = None) -> float:
        """How long before ``t_s`` (default: now) the newest state sample was received: 0 if one was received at or
        after ``t_s``, ``inf`` if none ever was. The stream runs at 100 Hz, so more than a few periods means it has
        stopped (sim paused, killed, network cut) and every pose from now on is a frozen guess."""
        newest = self.history.newest_t()
        if newest is None:
            return math.inf
        now = self._clock() if t_s is None else t_s
        return max(0.0, now - newest)

