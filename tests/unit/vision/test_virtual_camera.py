"""The virtual camera: paper geometry, thin-lens blur, the z sweep's sharpness peak, pose history."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest

from aioadept.geometry import Pose, poses_close
from aioadept.robots import viper_s850 as kin
from aioadept.vision.sharpness import measure
from aioadept.vision.virtual_camera import (CalibrationTarget, LensOptics, PoseHistory, VirtualCamera,
                                            camera_facing_tool, disk_kernel, paper_approach_pose, paper_camera)

APPROACH = paper_approach_pose()


def sweep(cam: VirtualCamera, delta_z_mm: float, n_steps: int) -> list[float]:
    """Sharpness after 0, 1, ..., n_steps MoveToolZ(+delta_z) increments from the approach pose."""
    out = []
    for i in range(n_steps + 1):
        res = measure(cam.render(APPROACH @ Pose(z=i * delta_z_mm)))
        assert res.ok, res.error
        out.append(res.sharpness)
    return out


def test_approach_pose_is_where_init_move_leaves_the_robot():
    # Sim IK/FK and a plain tool-frame composition agree; the paper's example pose is the intermediate one.
    assert poses_close(APPROACH, paper_approach_pose(kin.forward), tol_mm=1e-6, tol_deg=1e-6)
    mid = kin.forward([-90, -30, 210, -90, 90, 0])
    assert poses_close(mid, Pose(-80, -481.0993, 112.5, 180, 90, 180), tol_mm=1e-3, tol_deg=1e-6)
    # The tool points along world -x there, so the 185 mm tool-z move lands at x = -80 - 185.
    assert APPROACH.x == pytest.approx(-265.0) and APPROACH.roll == pytest.approx(-178.5)


def test_camera_looks_back_along_tool_z_and_plus_z_brings_the_object_closer():
    cam = paper_camera(noise_sigma=0, working_distance_mm=300, focus_offset_mm=20)
    assert cam.object_distance_mm(APPROACH) == pytest.approx(300.0)
    assert cam.object_distance_mm(APPROACH @ Pose(z=5)) == pytest.approx(295.0)
    assert cam.focus_distance_mm == pytest.approx(280.0)
    corners = cam.project(APPROACH)
    centre = corners.mean(axis=0)
    assert centre == pytest.approx([512, 384], abs=0.5)  # the tool origin is on the optical axis
    assert camera_facing_tool(APPROACH, 300).to_matrix()[:3, 2] == pytest.approx(-APPROACH.to_matrix()[:3, 2])


def test_thin_lens_blur_and_depth_of_field():
    o = LensOptics()
    assert o.coc_px(280, 280) == 0.0
    assert o.blur_diameter_px(280, 280) == pytest.approx(o.psf_floor_px)
    # A depth of field of a few mm: circle of confusion <= 2 px within about +-1.5 mm, ~2.7 px at 2 mm.
    assert o.coc_px(281.4, 280) < 2.0 < o.coc_px(282.0, 280) < 3.0
    assert o.coc_px(278.6, 280) < 2.0 < o.coc_px(278.0, 280)
    # It grows with defocus on both sides (larger blur for a larger aperture).
    assert o.coc_px(290, 280) > o.coc_px(285, 280) and o.coc_px(270, 280) > o.coc_px(275, 280)
    assert LensOptics(f_number=1.4).coc_px(285, 280) == pytest.approx(2 * o.coc_px(285, 280))


def test_disk_kernel():
    assert disk_kernel(0.5).shape == (1, 1)
    k = disk_kernel(7.0)
    assert k.shape == (7, 7) and k.sum() == pytest.approx(1.0, abs=1e-6)
    assert np.allclose(k, k.T) and np.allclose(k, k[::-1, ::-1])
    assert k[3, 3] == k.max() and k[0, 0] < 0.2 * k[3, 3]  # a disk: the corners are (nearly) outside


@pytest.mark.parametrize("focus_offset_mm, delta_z_mm, n_steps", [(20.0, 2.0, 20), (11.0, 2.5, 10), (6.0, 1.5, 9)])
def test_z_sweep_peaks_within_one_step_of_the_focal_plane(focus_offset_mm, delta_z_mm, n_steps):
    cam = paper_camera(focus_offset_mm=focus_offset_mm, seed=7)
    s = sweep(cam, delta_z_mm, n_steps)
    peak = int(np.argmax(s))
    assert abs(peak * delta_z_mm - focus_offset_mm) <= delta_z_mm
    # One peak: it rises to the maximum, then falls (what the focus application's stop rule relies on).
    assert all(b > a for a, b in pairwise(s[:peak + 1]))
    assert all(b < a for a, b in pairwise(s[peak:]))


def test_default_sweep_matches_the_paper_experiment():
    # Defaults: focal plane 20 mm ahead, steps of 2 mm: the 10th step is the sharpest, and the ufloop stop rule
    # (stop at the first decrease) stops one step later.
    s = sweep(paper_camera(seed=3), 2.0, 12)
    assert int(np.argmax(s)) == 10
    first_drop = next(i for i in range(1, len(s)) if s[i] < s[i - 1])
    assert first_drop == 11
    assert s[10] > 4 * s[0]


def test_render_without_pose_is_background_with_noise():
    cam = paper_camera(seed=1, noise_sigma=2.0, background=18)
    img = cam.render(None)
    assert img.shape == (768, 1024) and img.dtype == np.uint8
    assert img.mean() == pytest.approx(18, abs=0.2) and img.std() == pytest.approx(2.0, abs=0.3)
    res = measure(img)
    assert not res.ok and "no object found" in res.error


def test_grab_uses_the_pose_source_at_the_frame_time():
    asked: list[float] = []

    def pose_at(t_s: float) -> Pose:
        asked.append(t_s)
        return APPROACH @ Pose(z=20)

    times = iter([100.0, 100.1])
    cam = paper_camera(pose_at, clock=lambda: next(times), camera_id="cam0", sleep=None)
    f0, f1 = cam.grab(), cam.grab()
    # The pose at the exposure's mid-time (5 ms exposure by default), then at its start (did the tool move during
    # the exposure? then it is blurred); t_s is the exposure start.
    assert asked == pytest.approx([100.0025, 100.0, 100.1025, 100.1])
    assert (f0.t_s, f1.t_s) == (100.0, 100.1) and (f0.seq, f1.seq) == (0, 1)
    assert (f0.exposure_s, f0.readout_s) == (0.005, pytest.approx(1024 * 768 * 8 / 1e9))
    assert f0.camera_id == "cam0" and measure(f0.image).ok


def test_target_must_fit():
    with pytest.raises(ValueError, match="do not fit"):
        CalibrationTarget(height_mm=5.0)


def test_pose_history_interpolates_position_and_rotation():
    h = PoseHistory()
    assert h.at(1.0) is None
    h.add(10.0, Pose(0, 0, 0, 0, 0, 0))
    h.add(11.0, Pose(10, 20, 30, 0, 0, 40))
    mid = h.at(10.25)
    assert (mid.x, mid.y, mid.z) == pytest.approx((2.5, 5.0, 7.5))
    assert mid.roll == pytest.approx(10.0)
    assert h.at(9.0) == Pose(0, 0, 0, 0, 0, 0)              # before the first sample: the first pose
    assert h.at(12.0).x == pytest.approx(10.0)               # after the last: the last pose
    h.add(10.5, Pose(99, 0, 0))                              # out of order: dropped
    assert h.at(10.5).x == pytest.approx(5.0)


def test_pose_history_forgets_old_samples():
    h = PoseHistory(max_age_s=1.0)
    for i in range(50):
        h.add(i * 0.1, Pose(x=i))
    assert len(h) <= 12 and h.at(0.0).x == pytest.approx(len(range(50)) - len(h))
    assert not math.isnan(h.at(100.0).x)


def test_a_tool_moving_along_the_axis_during_the_exposure_is_blurred_by_its_travel():
    """Motion blur: the frame of a tool crossing the focal plane during the exposure integrates the
    defocus of every instant, so it is less sharp than a still frame at its mid-exposure pose; the faster, the
    less sharp; a still tool renders exactly as before."""
    cam = paper_camera(None, focus_offset_mm=20.0, noise_sigma=0.0, sleep=None)
    still = measure(cam.render(APPROACH @ Pose(z=20))).sharpness

    def moving(travel_mm: float) -> float:
        poses = [APPROACH @ Pose(z=20 + travel_mm * ((k + 0.5) / 5 - 0.5)) for k in range(5)]
        return measure(cam.render(APPROACH @ Pose(z=20), exposure_poses=poses)).sharpness

    assert moving(0.0) == pytest.approx(still)
    assert still > moving(1.0) > moving(4.0)

    speed_mm_s = 200.0

    def pose_at(t_s: float) -> Pose:  # the tool crossing the plane at 200 mm/s, at the plane at t = 100.0025
        return APPROACH @ Pose(z=20 + speed_mm_s * (t_s - 100.0025))

    grabbed = paper_camera(pose_at, focus_offset_mm=20.0, noise_sigma=0.0, clock=lambda: 100.0, sleep=None).grab()
    assert measure(grabbed.image).sharpness == pytest.approx(moving(speed_mm_s * 0.005), rel=1e-6)


def test_sharpness_is_continuous_in_the_blur_diameter():
    """Kernels between quarter pixels are blended: the image changes by little for a small change of focus (a
    kernel rounded to quarter pixels made sharpness a staircase in z, which a sweep's fit would read as signal)."""
    cam = paper_camera(None, focus_offset_mm=20.0, noise_sigma=0.0, sleep=None)
    k = cam._kernel(5.1)
    assert k.sum() == pytest.approx(1.0, abs=1e-5)
    a, b = cam.render(APPROACH @ Pose(z=16.0)), cam.render(APPROACH @ Pose(z=16.02))
    assert 0 < np.abs(a.astype(int) - b.astype(int)).max() <= 2
