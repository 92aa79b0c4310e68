"""Camera-to-robot calibration: the camera model the part locator uses, the cell file's ``[calibration]`` table,
and the routine that estimates the camera's pose in the robot base frame from views of a marker on the tool.

Where it sits: :mod:`aioadept.vision.locate` turns pixels into robot base coordinates with a
:class:`CameraCalibration` (intrinsics + the camera frame in the base frame + the table plane); ``aioadept
calibrate`` (:mod:`aioadept.cli.calibrate`) moves the robot through poses, collects marker views and calls
:func:`calibrate_eye_to_hand`, which writes the table back.

Conventions (those of :mod:`aioadept.vision.virtual_camera` and the world camera): the camera frame has OpenCV axes
(z along the optical axis, x right, y down in the image); its pose is an Adept TRANS (mm, Z-Y-Z degrees) in the robot
base frame, so a camera looking straight down has pitch 180. The pinhole's intrinsics are OpenCV's ``K`` and
distortion coefficients (``k1 k2 p1 p2 [k3 ...]``).

The estimation (why not ``cv2.calibrateHandEye``: the OpenCV 5.0 Python build this project pins does not export it
nor ``calibrateRobotWorldHandEye``): one ``cv2.solvePnP`` (``SOLVEPNP_IPPE_SQUARE``) per view gives the marker in
the camera; the fixed camera X (camera in base) and the unknown marker mount Y (marker in tool) satisfy
``X M_i = B_i Y`` for every view (B_i: the tool in base, M_i: the marker in the camera). Pairs of views give
``A X = X C`` (``A = B_i B_j^-1``, ``C = M_i M_j^-1``), solved in closed form as Park & Martin do (the rotation from the
rotation axes by SVD, then the translation by linear least squares); that start is refined by Gauss-Newton on the
reprojection error of every marker corner in every view, so the result is the maximum-likelihood estimate under
pixel noise rather than a fit of PnP's noisy depths.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from aioadept.cell.schema import Range, check_ranges, check_section, ranged
from aioadept.errors import ConfigError
from aioadept.geometry import Pose, decompose, inverse_transform

_XYZ = Range(-5000.0, 5000.0, unit="mm")
_ANGLE = Range(-360.0, 360.0, unit="deg")
_FOCAL = Range(1.0, 1e6, unit="px")
_CENTRE = Range(0.0, 1e5, unit="px")
_SIZE = Range(16, 16384, integer=True, unit="px")
_DIST = Range(-1000.0, 1000.0)
MAX_DIST_COEFFS = 14
"""OpenCV's longest distortion model (k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4 tx ty)."""


@dataclass(frozen=True, slots=True)
class CameraCalibration:
    """A calibrated camera in the robot cell: intrinsics (px), distortion, the camera frame in the robot base frame
    (mm, Adept Z-Y-Z degrees, OpenCV camera axes) and the table plane's height in the base frame."""

    fx_px: float = ranged(1735.9, _FOCAL)
    fy_px: float = ranged(1735.9, _FOCAL)
    cx_px: float = ranged(512.0, _CENTRE)
    cy_px: float = ranged(384.0, _CENTRE)
    width_px: int = ranged(1024, _SIZE)
    height_px: int = ranged(768, _SIZE)
    dist: tuple[float, ...] = ()
    """OpenCV distortion coefficients; empty: none."""
    x_mm: float = ranged(450.0, _XYZ)
    y_mm: float = ranged(0.0, _XYZ)
    z_mm: float = ranged(900.0, _XYZ)
    yaw_deg: float = ranged(0.0, _ANGLE)
    pitch_deg: float = ranged(180.0, _ANGLE)
    roll_deg: float = ranged(0.0, _ANGLE)
    table_z_mm: float = ranged(0.0, Range(-2000.0, 2000.0, unit="mm"))
    """Height of the table top in the base frame: the plane the locator intersects pixel rays with."""
    rms_px: float | None = None
    """Written by the calibration routine: RMS reprojection error of its views (information only)."""
    views: int | None = None
    """Written by the calibration routine: how many views it used (information only)."""

    # -- the model ---------------------------------------------------------------------------------------
    @property
    def K(self) -> np.ndarray:  # noqa: N802 (OpenCV's name)
        return np.array([[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        return np.array(self.dist, float) if self.dist else np.zeros(5)

    @property
    def pose(self) -> Pose:
        """The camera frame in the robot base frame."""
        return Pose(self.x_mm, self.y_mm, self.z_mm, self.yaw_deg, self.pitch_deg, self.roll_deg)

    @property
    def base_from_camera(self) -> np.ndarray:
        """4 x 4: camera coordinates -> base coordinates (mm)."""
        return self.pose.to_matrix()

    def with_pose(self, pose: Pose | np.ndarray, **info: Any) -> CameraCalibration:
        """The same intrinsics with another camera pose (a Pose or a 4 x 4 base_from_camera)."""
        p = pose if isinstance(pose, Pose) else decompose(np.asarray(pose, float))
        return dataclasses.replace(self, x_mm=p.x, y_mm=p.y, z_mm=p.z, yaw_deg=p.yaw, pitch_deg=p.pitch,
                                   roll_deg=p.roll, **info)

    def project(self, points_base: np.ndarray) -> np.ndarray:
        """Pixel coordinates (N x 2) of base-frame points (N x 3, mm), with the distortion."""
        import cv2

        cam_from_base = inverse_transform(self.base_from_camera)
        rvec, _ = cv2.Rodrigues(cam_from_base[:3, :3])
        pts = np.asarray(points_base, float).reshape(-1, 1, 3)
        uv, _ = cv2.projectPoints(pts, rvec, cam_from_base[:3, 3], self.K, self.dist_coeffs)
        return uv.reshape(-1, 2)

    def rays(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(origin (3,), unit directions N x 3) in the base frame of the rays through ``pixels`` (N x 2)."""
        import cv2

        px = np.asarray(pixels, float).reshape(-1, 1, 2)
        norm = cv2.undistortPoints(px, self.K, self.dist_coeffs).reshape(-1, 2)  # undistorted, z = 1
        d_cam = np.hstack([norm, np.ones((len(norm), 1))])
        m = self.base_from_camera
        d = d_cam @ m[:3, :3].T
        return m[:3, 3].copy(), d / np.linalg.norm(d, axis=1, keepdims=True)

    def on_plane(self, pixels: np.ndarray, z_mm: float) -> np.ndarray:
        """Base-frame points (N x 3) where the rays through ``pixels`` meet the horizontal plane ``z = z_mm``.

        Raises ValueError when a ray runs parallel to the plane or meets it behind the camera.
        """
        origin, d = self.rays(pixels)
        dz = d[:, 2]
        if np.any(np.abs(dz) < 1e-9):
            raise ValueError("a pixel ray runs parallel to the table plane")
        s = (z_mm - origin[2]) / dz
        if np.any(s <= 0):
            raise ValueError(f"the plane z = {z_mm:g} mm is behind the camera for some pixels")
        return origin + s[:, None] * d

    # -- the cell file -------------------------------------------------------------------------------------
    @classmethod
    def from_table(cls, table: Any, where: str = "[calibration]") -> CameraCalibration:
        """The calibration of a ``[calibration]`` table; :class:`ConfigError` (one line naming ``where`` and the
        key) for an unknown key, a wrong type or a value out of range."""
        data = check_section(_CalibrationTable, table, where)
        dist = data.pop("dist", [])
        if len(dist) > MAX_DIST_COEFFS or len(dist) not in (0, 4, 5, 8, 12, 14) or not all(
                _DIST.contains(v) for v in dist):
            raise ConfigError(f"{where}: dist = {dist!r}: expected 0, 4, 5, 8, 12 or 14 OpenCV distortion "
                              f"coefficients, each a number in {_DIST.text}")
        try:
            cal = cls(**data, dist=tuple(float(v) for v in dist))
            check_ranges(cal)
        except ValueError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        if cal.cx_px > cal.width_px or cal.cy_px > cal.height_px:
            raise ConfigError(f"{where}: the principal point ({cal.cx_px:g}, {cal.cy_px:g}) px lies outside the "
                              f"{cal.width_px} x {cal.height_px} px image")
        cam_z = cal.base_from_camera[:3, 2]
        if not (cal.z_mm > cal.table_z_mm and cam_z[2] < 0):
            raise ConfigError(f"{where}: the camera (z_mm = {cal.z_mm:g}, optical axis {_vec(cam_z)}) does not look "
                              f"down at the table (table_z_mm = {cal.table_z_mm:g})")
        return cal

    def to_table(self) -> dict[str, Any]:
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["dist"] = list(self.dist)
        return {k: v for k, v in out.items() if v is not None}

    def to_toml(self) -> str:
        """The ``[calibration]`` table as TOML text (what ``aioadept calibrate`` prints or writes)."""
        lines = ["[calibration]"]
        for key, value in self.to_table().items():
            if isinstance(value, list):
                lines.append(f"{key} = [{', '.join(repr(float(v)) for v in value)}]")
            elif isinstance(value, float):
                lines.append(f"{key} = {value!r}")
            else:
                lines.append(f"{key} = {value}")
        return "\n".join(lines) + "\n"


@dataclass(slots=True)
class _CalibrationTable:
    """The keys a ``[calibration]`` table may hold, with their TOML types (ranges: :class:`CameraCalibration`)."""

    fx_px: float = 0.0
    fy_px: float = 0.0
    cx_px: float = 0.0
    cy_px: float = 0.0
    width_px: int = 0
    height_px: int = 0
    dist: list[float] = field(default_factory=list)
    x_mm: float = 0.0
    y_mm: float = 0.0
    z_mm: float = 0.0
    yaw_deg: float = 0.0
    pitch_deg: float = 0.0
    roll_deg: float = 0.0
    table_z_mm: float = 0.0
    rms_px: float = 0.0
    views: int = 0


def _vec(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:.2f}" for x in v) + ")"


def load_calibration(path: str | Path) -> CameraCalibration:
    """The ``[calibration]`` table of a TOML cell file; :class:`ConfigError` for a missing file, bad TOML or no
    such table."""
    from aioadept.cell.schema import load_toml

    data = load_toml(path)
    if "calibration" not in data:
        raise ConfigError(f"{path}: no [calibration] table (run aioadept calibrate to make one)")
    return CameraCalibration.from_table(data["calibration"], f"{path} [calibration]")


def write_calibration(path: str | Path, cal: CameraCalibration) -> None:
    """Put ``cal`` into the TOML file ``path`` as its ``[calibration]`` table: an existing table is replaced (its
    lines, up to the next table header), everything else in the file is kept as written; a new file is created."""
    p = Path(path)
    text = p.read_text(encoding="utf-8") if p.exists() else ""
    lines = text.splitlines()
    out: list[str] = []
    skipping = False
    for line in lines:
        head = line.strip()
        if head.startswith("["):
            skipping = head.replace(" ", "") == "[calibration]"
            if skipping:
                continue
        if not skipping:
            out.append(line)
    body = "\n".join(out).rstrip()
    new = (body + "\n\n" if body else "") + cal.to_toml()
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(new, encoding="utf-8")
    tmp.replace(p)


# ------------------------------------------------------------------------------------------------ estimation
def marker_object_points(marker_mm: float) -> np.ndarray:
    """The marker's corners in its own frame (4 x 3, mm), in cv2.aruco's order (top-left, top-right, bottom-right,
    bottom-left of the marker image), as ``SOLVEPNP_IPPE_SQUARE`` wants them."""
    h = marker_mm / 2.0
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


def marker_in_camera(corners_px: np.ndarray, K: np.ndarray, dist: np.ndarray,  # noqa: N803
                     marker_mm: float) -> np.ndarray:
    """4 x 4 camera_from_marker of one detected marker (``corners_px`` 4 x 2, cv2.aruco's order), by
    ``cv2.solvePnP`` with ``SOLVEPNP_IPPE_SQUARE``. Raises ValueError when PnP fails."""
    import cv2

    ok, rvec, tvec = cv2.solvePnP(marker_object_points(marker_mm), np.asarray(corners_px, float).reshape(4, 1, 2),
                                  K, dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    if not ok:
        raise ValueError("solvePnP found no pose for the marker")
    m = np.eye(4)
    m[:3, :3] = cv2.Rodrigues(rvec)[0]
    m[:3, 3] = tvec.ravel()
    return m


@dataclass(frozen=True, slots=True)
class MarkerView:
    """One calibration view: the tool pose the robot reported (base frame) and the marker's corners (px)."""

    tool: Pose
    corners_px: np.ndarray


@dataclass(frozen=True, slots=True)
class HandEyeResult:
    """The camera in the base frame, the marker on the tool, and the RMS reprojection error over all corners."""

    base_from_camera: np.ndarray
    tool_from_marker: np.ndarray
    rms_px: float
    views: int


def _rotation_log(r: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.Rodrigues(r)[0].ravel()


def _closed_form(b: list[np.ndarray], m: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """X (base_from_camera) and Y (tool_from_marker) from ``X M_i = B_i Y`` by Park & Martin's method on pairs."""
    alphas, betas, pairs = [], [], []
    n = len(b)
    for i in range(n):
        for j in range(i + 1, n):
            a = b[i] @ inverse_transform(b[j])
            c = m[i] @ inverse_transform(m[j])
            la, lc = _rotation_log(a[:3, :3]), _rotation_log(c[:3, :3])
            if np.linalg.norm(la) < math.radians(2.0):  # too small a turn to carry the rotation axis
                continue
            alphas.append(la)
            betas.append(lc)
            pairs.append((a, c))
    if len(pairs) < 2:
        raise ValueError("the views turn the tool too little: vary the tool's orientation about at least two "
                         "different axes (more than 2 degrees apart)")
    # R_X maps each C's rotation axis onto A's: the orthogonal Procrustes problem (Kabsch).
    h = np.array(betas).T @ np.array(alphas)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rx = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    # (R_A - I) t_X = R_X t_C - t_A, stacked over the pairs.
    lhs = np.vstack([a[:3, :3] - np.eye(3) for a, _ in pairs])
    rhs = np.concatenate([rx @ c[:3, 3] - a[:3, 3] for a, c in pairs])
    tx = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    x = np.eye(4)
    x[:3, :3], x[:3, 3] = rx, tx
    # Y = B_i^-1 X M_i for each view; average (rotation by SVD projection of the mean).
    ys = [inverse_transform(bi) @ x @ mi for bi, mi in zip(b, m, strict=True)]
    y = np.eye(4)
    u, _, vt = np.linalg.svd(sum(yi[:3, :3] for yi in ys))
    y[:3, :3] = u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
    y[:3, 3] = np.mean([yi[:3, 3] for yi in ys], axis=0)
    return x, y


def _pack(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.concatenate([_rotation_log(x[:3, :3]), x[:3, 3], _rotation_log(y[:3, :3]), y[:3, 3]])


def _unpack(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    import cv2

    out = []
    for k in (0, 6):
        m = np.eye(4)
        m[:3, :3] = cv2.Rodrigues(p[k:k + 3])[0]
        m[:3, 3] = p[k + 3:k + 6]
        out.append(m)
    return out[0], out[1]


def _residuals(p: np.ndarray, b: list[np.ndarray], corners: list[np.ndarray], obj: np.ndarray, K: np.ndarray,  # noqa: N803
               dist: np.ndarray) -> np.ndarray:
    import cv2

    x, y = _unpack(p)
    cam_from_base = inverse_transform(x)
    res = []
    for bi, ci in zip(b, corners, strict=True):
        cm = cam_from_base @ bi @ y  # camera_from_marker predicted by the two unknowns
        uv, _ = cv2.projectPoints(obj.reshape(-1, 1, 3), cv2.Rodrigues(cm[:3, :3])[0], cm[:3, 3], K, dist)
        res.append((uv.reshape(-1, 2) - ci).ravel())
    return np.concatenate(res)


def _refine(p: np.ndarray, *args: Any, iterations: int = 30) -> np.ndarray:
    """Levenberg-Marquardt on the reprojection residuals (numeric Jacobian; 12 unknowns, so cheap)."""
    lam = 1e-3
    r = _residuals(p, *args)
    cost = float(r @ r)
    for _ in range(iterations):
        jac = np.empty((len(r), len(p)))
        for k in range(len(p)):
            step = 1e-6 if k % 6 < 3 else 1e-4  # radians / mm
            q = p.copy()
            q[k] += step
            jac[:, k] = (_residuals(q, *args) - r) / step
        jtj, jtr = jac.T @ jac, jac.T @ r
        while True:
            delta = np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-12), -jtr)
            q = p + delta
            rq = _residuals(q, *args)
            cq = float(rq @ rq)
            if cq < cost:
                p, r, lam = q, rq, max(lam / 10, 1e-9)
                improved = cost - cq
                cost = cq
                break
            lam *= 10
            if lam > 1e8:
                return p
        if improved < 1e-12 * max(cost, 1.0):
            break
    return p


def calibrate_eye_to_hand(views: Sequence[MarkerView], K: np.ndarray, dist: np.ndarray,  # noqa: N803
                          marker_mm: float) -> HandEyeResult:
    """The fixed camera's pose in the robot base frame (and the marker's on the tool) from >= 3 views of a marker
    carried by the tool; see the module docstring for the method. Raises ValueError for too few views or views that
    do not turn the tool about two different axes."""
    if len(views) < 3:
        raise ValueError(f"calibration needs at least 3 marker views, got {len(views)}")
    K = np.asarray(K, float)  # noqa: N806
    dist = np.asarray(dist, float)
    b = [v.tool.to_matrix() for v in views]
    corners = [np.asarray(v.corners_px, float).reshape(4, 2) for v in views]
    m = [marker_in_camera(c, K, dist, marker_mm) for c in corners]
    x, y = _closed_form(b, m)
    obj = marker_object_points(marker_mm)
    p = _refine(_pack(x, y), b, corners, obj, K, dist)
    x, y = _unpack(p)
    r = _residuals(p, b, corners, obj, K, dist)
    return HandEyeResult(x, y, float(np.sqrt(np.mean(r.reshape(-1, 2) ** 2) * 2)), len(views))


__all__ = ["CameraCalibration", "HandEyeResult", "MarkerView", "calibrate_eye_to_hand", "load_calibration",
           "marker_in_camera", "marker_object_points", "write_calibration"]
