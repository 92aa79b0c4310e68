"""The fixed camera above the table: renders the simulated world's parts and their ArUco markers.

Where it sits: the sim publishes :class:`aioadept.bus.messages.WorldState` on ``world.state`` beside the robot
state; a :class:`WorldStateFollower` (one owned thread) keeps the newest sample; :class:`WorldCameraSource` renders
a frame from it on each grab, and the acquisition service buffers the frames like those of any camera. The world's
configuration (what the parts look like, where the camera is) comes from the cell file's ``[world]`` table
(:mod:`aioadept.cell.world`). :class:`WorldView` is the pure part (parts in, image out), used by the source, the
recording (a colour view without noise) and the tests.

Camera model, the virtual camera's (:mod:`aioadept.vision.virtual_camera`): a pinhole with OpenCV axes at
:meth:`aioadept.world.WorldCamera.pose`, :class:`~aioadept.vision.virtual_camera.LensOptics` (4.65 um pixels,
the cell file's focal length and f-number and size), the lens focused on the table top, the sensor placed where
that plane is imaged (so the focal length in pixels is that image distance over the pixel size); the thin-lens
blur of the table-top plane for the whole frame (parts are a few cm tall: their blur differs by a fraction of a
pixel at the distances a cell uses) and the same additive Gaussian sensor noise (:class:`~aioadept.vision.
virtual_camera.NoiseField`), mono8.

Drawing is OpenCV's: each part's silhouette (the convex hull of its projected outline, in a darker shade of its
colour: the sides seen in perspective) and its top face (``cv2.fillConvexPoly``, anti-aliased), then the marker
label (``cv2.aruco.generateImageMarker`` on a white margin, ``cv2.warpPerspective`` onto the top face). Parts are
drawn farthest first, so a nearer one hides what is behind it (no other occlusion: the world has no collisions).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import cv2
import numpy as np

from aioadept.geometry import Pose, inverse_transform
from aioadept.vision.sources import Camera, Frame
from aioadept.vision.virtual_camera import (DEFAULT_EXPOSURE_MS, LensOptics, NoiseField, TopicFollower, disk_kernel,
                                           gige_readout_ms)
from aioadept.world import PartSpec, PartState, WorldCamera, WorldConfig, flat_matrix, label_mm, marker_bits

log = logging.getLogger(__name__)

TABLE_GREY = (200, 200, 196)
"""The table top (BGR): a light grey, so dark parts and the labels' white both stand out."""
_CIRCLE_POINTS = 64


def _shade(rgb: tuple[int, int, int], k: float) -> tuple[int, int, int]:
    """BGR of an RGB colour scaled by ``k`` (the sides are darker than the lit top)."""
    r, g, b = rgb
    return (int(b * k), int(g * k), int(r * k))


class WorldView:
    """Renders parts (:class:`aioadept.world.PartState`) as the world's camera sees them; pure and cheap to
    call (the marker images are generated once). ``seed`` makes the noise reproducible."""

    def __init__(self, world: WorldConfig, *, seed: int | None = None) -> None:
        if world.camera is None:
            raise ValueError("the world has no [world.camera]")
        self.world = world
        cam: WorldCamera = world.camera
        self.camera = cam
        self.optics = LensOptics(focal_length_mm=cam.focal_length_mm, f_number=cam.f_number,
                                 width_px=cam.width_px, height_px=cam.height_px)
        self.camera_pose = cam.pose()
        self._world_to_cam = inverse_transform(self.camera_pose.to_matrix())
        self.focus_distance_mm = float(self._world_to_cam[2] @ np.array([cam.x_mm, cam.y_mm, world.table_z_mm, 1]))
        v = self.optics.image_distance_mm(self.focus_distance_mm)
        f_px = v / self.optics.pixel_size_mm
        self.camera_matrix = np.array([[f_px, 0.0, cam.width_px / 2.0], [0.0, f_px, cam.height_px / 2.0],
                                       [0.0, 0.0, 1.0]])
        """The pinhole's intrinsics K (px); no lens distortion."""
        self.blur_px = self.optics.blur_diameter_px(self.focus_distance_mm, self.focus_distance_mm)
        self._kernel = disk_kernel(self.blur_px)
        self.noise = NoiseField(cam.height_px, cam.width_px, cam.noise_sigma, seed=seed)
        self._labels: dict[int, np.ndarray] = {}
        self._lock = threading.Lock()

    # -- geometry ------------------------------------------------------------------------------------------
    def project(self, points_world: np.ndarray) -> np.ndarray:
        """Pixel coordinates (N x 2) of world points (N x 3, mm); points behind the lens give NaN."""
        pts = np.asarray(points_world, float).reshape(-1, 3)
        cam = (self._world_to_cam[:3, :3] @ pts.T).T + self._world_to_cam[:3, 3]
        z = cam[:, 2:3]
        uv = (self.camera_matrix @ (cam / np.where(z > 0, z, np.nan)).T).T[:, :2]
        return uv

    def marker_corners_mm(self, spec: PartSpec, state: PartState) -> np.ndarray:
        """World coordinates (4 x 3 mm) of a part's marker corners, in OpenCV's order (top-left, top-right,
        bottom-right, bottom-left of the marker image: (-s/2, s/2), (s/2, s/2), (s/2, -s/2), (-s/2, -s/2))."""
        return self._on_top(spec, state, spec.marker_mm / 2)

    def _on_top(self, spec: PartSpec, state: PartState, half: float) -> np.ndarray:
        local = np.array([[-half, half, spec.height_mm, 1], [half, half, spec.height_mm, 1],
                          [half, -half, spec.height_mm, 1], [-half, -half, spec.height_mm, 1]])
        return (state.pose.to_matrix() @ local.T).T[:, :3]

    def _outline(self, spec: PartSpec, z_mm: float) -> np.ndarray:
        """The part's outline at height ``z_mm`` in its own frame (N x 4 homogeneous)."""
        if spec.shape == "cylinder":
            a = np.linspace(0, 2 * math.pi, _CIRCLE_POINTS, endpoint=False)
            r = spec.size_mm[0] / 2
            return np.stack([r * np.cos(a), r * np.sin(a), np.full_like(a, z_mm), np.ones_like(a)], axis=1)
        hx, hy = spec.size_mm[0] / 2, spec.size_mm[1] / 2
        return np.array([[-hx, -hy, z_mm, 1], [hx, -hy, z_mm, 1], [hx, hy, z_mm, 1], [-hx, hy, z_mm, 1]])

    # -- drawing -------------------------------------------------------------------------------------------
    def _label(self, marker: int, px: int) -> np.ndarray:
        """The marker on its white label, ``px`` square (mono8), cached per marker and size."""
        key = marker * 100_000 + px
        img = self._labels.get(key)
        if img is None:
            bits = marker_bits(self.world.aruco_dict)
            dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.world.aruco_dict))
            module = max(1, round(px / (bits + 4)))
            inner = cv2.aruco.generateImageMarker(dictionary, marker, module * (bits + 2), borderBits=1)
            img = cv2.copyMakeBorder(inner, module, module, module, module, cv2.BORDER_CONSTANT, value=255)
            if len(self._labels) > 512:
                self._labels.clear()
            self._labels[key] = img
        return img

    def render_colour(self, parts: Sequence[PartState], tool: Pose | None = None) -> np.ndarray:
        """The scene as a BGR image, sharp and without noise (the recording's view); ``tool``: where the robot's
        tool is, to draw the world's tool marker there (drawn last: the tool is above the parts; the arm itself
        is not drawn)."""
        cam = self.camera
        img = np.empty((cam.height_px, cam.width_px, 3), np.uint8)
        img[:] = TABLE_GREY
        specs = {p.id: p for p in self.world.parts}
        # farthest first: the depth of each part's top centre along the optical axis
        order = []
        for st in parts:
            spec = specs.get(st.id)
            if spec is None:
                continue
            top = st.pose.to_matrix() @ np.array([0, 0, spec.height_mm, 1])
            order.append((float(self._world_to_cam[2] @ top), spec, st))
        order.sort(key=lambda t: -t[0])
        for depth, spec, st in order:
            if depth <= self.optics.focal_length_mm:
                continue  # at or behind the lens
            self._draw_part(img, spec, st)
        if tool is not None:
            self._draw_tool_marker(img, tool)
        return img

    def _draw_part(self, img: np.ndarray, spec: PartSpec, st: PartState) -> None:
        m = st.pose.to_matrix()
        bottom = self.project((m @ self._outline(spec, 0.0).T).T[:, :3])
        top = self.project((m @ self._outline(spec, spec.height_mm).T).T[:, :3])
        if not (np.all(np.isfinite(bottom)) and np.all(np.isfinite(top))):
            return
        hull = cv2.convexHull(np.vstack([bottom, top]).astype(np.float32))
        shift = 4  # sub-pixel vertices: 1/16 px
        scale = float(1 << shift)
        cv2.fillConvexPoly(img, np.round(hull * scale).astype(np.int32), _shade(spec.colour, 0.6), cv2.LINE_AA,
                           shift)
        top_hull = cv2.convexHull(top.astype(np.float32))
        cv2.fillConvexPoly(img, np.round(top_hull * scale).astype(np.int32), _shade(spec.colour, 1.0), cv2.LINE_AA,
                           shift)
        if spec.marker is not None:
            self._draw_label(img, spec, st)

    def _draw_label(self, img: np.ndarray, spec: PartSpec, st: PartState) -> None:
        half = label_mm(spec.marker_mm, self.world.aruco_dict) / 2
        self._warp_label(img, spec.marker, self._on_top(spec, st, half))

    def tool_marker_corners_mm(self, tool: Pose, half: float | None = None) -> np.ndarray:
        """World coordinates (4 x 3 mm) of the tool marker's corners (OpenCV's order, as
        :meth:`marker_corners_mm`) with the tool at ``tool``; ``half``: half the side drawn (default the marker's)."""
        tm = self.world.tool_marker
        if tm is None:
            raise ValueError("the world has no [world.tool_marker]")
        h = tm.marker_mm / 2 if half is None else half
        local = np.array([[-h, h, 0, 1], [h, h, 0, 1], [h, -h, 0, 1], [-h, -h, 0, 1]], float)
        return (tool.to_matrix() @ tm.mount() @ local.T).T[:, :3]

    def _draw_tool_marker(self, img: np.ndarray, tool: Pose) -> None:
        tm = self.world.tool_marker
        if tm is None:
            return
        corners = self.tool_marker_corners_mm(tool, label_mm(tm.marker_mm, self.world.aruco_dict) / 2)
        normal_towards_camera = self._world_to_cam[2, :3] @ (tool.to_matrix() @ tm.mount())[:3, 2] < 0
        depth = self._world_to_cam[2] @ np.append(corners.mean(axis=0), 1.0)
        if normal_towards_camera and depth > self.optics.focal_length_mm:
            self._warp_label(img, tm.marker, corners)  # its back (plain plate) is not drawn

    def _warp_label(self, img: np.ndarray, marker: int, corners_mm: np.ndarray) -> None:
        corners = self.project(corners_mm).astype(np.float32)
        if not np.all(np.isfinite(corners)):
            return
        side = float(max(np.linalg.norm(corners[1] - corners[0]), np.linalg.norm(corners[3] - corners[0])))
        if side < 6:
            return  # smaller than a few pixels: nothing a detector could read
        label = self._label(marker, max(24, int(side * 2)))
        n = label.shape[0]
        # the label's outer edges, in OpenCV's convention (pixel centres at integers): -0.5 .. n - 0.5
        src = np.float32([[-0.5, -0.5], [n - 0.5, -0.5], [n - 0.5, n - 0.5], [-0.5, n - 0.5]])
        x0, y0 = np.floor(corners.min(axis=0)).astype(int) - 2
        x1, y1 = np.ceil(corners.max(axis=0)).astype(int) + 2
        h, w = img.shape[:2]
        x0, y0, x1, y1 = max(0, x0), max(0, y0), min(w, x1), min(h, y1)
        if x1 <= x0 or y1 <= y0:
            return
        homography = cv2.getPerspectiveTransform(src, corners - np.float32([x0, y0]))
        size = (int(x1 - x0), int(y1 - y0))
        warped = cv2.warpPerspective(label, homography, size, flags=cv2.INTER_AREA)
        mask = cv2.warpPerspective(np.full_like(label, 255), homography, size, flags=cv2.INTER_LINEAR)
        alpha = (mask.astype(np.float32) / 255.0)[..., None]
        roi = img[y0:y1, x0:x1].astype(np.float32)
        img[y0:y1, x0:x1] = np.round(roi * (1 - alpha) + warped[..., None].astype(np.float32) * alpha).astype(np.uint8)

    def render(self, parts: Sequence[PartState], tool: Pose | None = None) -> np.ndarray:
        """A mono8 frame of the scene with the lens blur and the sensor noise (``tool``: :meth:`render_colour`)."""
        grey = cv2.cvtColor(self.render_colour(parts, tool), cv2.COLOR_BGR2GRAY)
        if self._kernel.shape[0] > 1:
            grey = cv2.filter2D(grey, -1, self._kernel, borderType=cv2.BORDER_REPLICATE)
        with self._lock:
            return self.noise.add(grey)


def parts_at_rest(world: WorldConfig) -> tuple[PartState, ...]:
    """The parts where the cell file puts them (before any world state has arrived)."""
    return tuple(PartState(p.id, Pose.from_matrix(flat_matrix(p.x_mm, p.y_mm, world.table_z_mm, p.yaw_deg)))
                 for p in world.parts if not p.fed)  # the feeder's queue has brought none yet


class WorldStateFollower(TopicFollower):
    """Subscribes to ``world.state`` and keeps the newest :class:`aioadept.bus.messages.WorldState` (one owned
    non-daemon thread; :meth:`start`/:meth:`stop` or a context manager), stamped on receipt with ``clock()``."""

    WHAT = "world state"

    def __init__(self, endpoint: str, *, curve: Any = None, clock: Callable[[], float] = time.time) -> None:
        from aioadept.bus.messages import WORLD_STATE_TOPIC

        super().__init__(endpoint, WORLD_STATE_TOPIC, curve=curve, clock=clock)
        self.latest: Any = None
        self.received_t: float | None = None

    def decode(self, payload: bytes) -> Any:
        from aioadept.bus.messages import WorldState

        return WorldState.from_bytes(payload)

    def take(self, state: Any, t_s: float) -> None:
        self.latest, self.received_t = state, t_s

    def parts(self) -> tuple[PartState, ...] | None:
        """The parts of the newest sample, or None before the first."""
        st = self.latest
        return None if st is None else st.parts

    def state_age_s(self, t_s: float | None = None) -> float:
        """How long before ``t_s`` (default: now) the newest sample arrived (0 if at or after it, ``inf`` before
        the first): stamped on each frame, so the node refuses to answer from a world that stopped updating."""
        received = self.received_t
        if received is None:
            return math.inf
        return max(0.0, (self._clock() if t_s is None else t_s) - received)

class WorldCameraSource(Camera):
    """The world's camera as a frame source: each grab renders the parts of ``parts()`` (the follower's newest
    sample; before one arrives, the parts where the cell file puts them) and delivers the frame after the
    exposure and readout, as :class:`~aioadept.vision.virtual_camera.VirtualCamera` does. The parts shown are
    those of the newest sample at the exposure's start: with the stream at 100 Hz, at most one period old.
    ``state_age(t_s)`` (the follower's :meth:`WorldStateFollower.state_age_s`) is stamped on each frame as its
    ``pose_age_s``, so a node with ``max_state_age`` refuses frames of a world stream that went silent (or never
    came); without it (no stream) the frames carry None and the parts stay where the file puts them. ``tool_at``
    (the robot state follower's ``pose_at``): the tool pose at a time, where the world's tool marker is drawn (None,
    or no pose yet: no marker)."""

    can_trigger = True

    def __init__(self, view: WorldView, parts: Callable[[], Sequence[PartState] | None], *,
                 state_age: Callable[[float], float] | None = None,
                 tool_at: Callable[[float], Pose | None] | None = None, camera_id: str = "world", clock: Callable[[], float] = time.time,
                 exposure_ms: float = DEFAULT_EXPOSURE_MS, readout_ms: float | None = None,
                 sleep: Callable[[float], None] | None = time.sleep) -> None:
        self.view = view
        self._parts = parts
        self.camera_id = camera_id
        self._clock = clock
        self.exposure_ms = float(exposure_ms)
        self.readout_ms = float(readout_ms) if readout_ms is not None else \
            gige_readout_ms(view.camera.width_px * view.camera.height_px)
        self._sleep = sleep
        self._state_age = state_age
        self._tool_at = tool_at if view.world.tool_marker is not None else None
        self._seq = 0
        self._rest = parts_at_rest(view.world)

    def grab(self) -> Frame:
        t_s = self._clock()
        parts = self._parts()
        tool = self._tool_at(t_s) if self._tool_at is not None else None
        image = self.view.render(self._rest if parts is None else parts, tool)
        exposure_s, readout_s = self.exposure_ms / 1e3, self.readout_ms / 1e3
        if self._sleep is not None:
            left = t_s + exposure_s + readout_s - self._clock()
            if left > 0:
                self._sleep(left)  # the physical exposure + readout time, not a readiness wait
        # the age of the world state shown, as the virtual camera stamps its pose's: the node's max_state_age check
        age = self._state_age(t_s) if self._state_age is not None else None
        frame = Frame(image, t_s, self.camera_id, self._seq, age, exposure_s, readout_s)
        self._seq += 1
        return frame


__all__ = ["TABLE_GREY", "WorldCameraSource", "WorldStateFollower", "WorldView", "parts_at_rest"]
