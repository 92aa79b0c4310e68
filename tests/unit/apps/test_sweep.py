"""The focus sweep's pure parts: the speed from the blur budget, the peak fit and its uncertainty, the
clock offsets, the state interpolation and the planned profile. No sockets."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from aioadept.apps.focus import FocusParams
from aioadept.apps.sweep_model import PeakFit, StateTrack, blur_model, clock_offset, fit_peak, profile_offset
from aioadept.apps.sweep_plan import check_sweep, plan_sweep, sweep_speed

SWEEP = FocusParams(mode="sweep")


def curve(z, z0=21.3, noise=0.0, seed=0):
    """Sharpness of a defocus blur: 1 / (hyperbola + slight skew), scaled like the virtual camera's (peak ~150)."""
    rng = np.random.default_rng(seed)
    inv = blur_model([0.2, 0.25, z0, 3.0, 0.01], np.asarray(z, float))
    return 150.0 / inv / blur_model([0.2, 0.25, z0, 3.0, 0.01], np.array([z0])).min() * (
        1 + noise * rng.standard_normal(len(z)))


def test_speed_keeps_the_travel_during_one_exposure_within_the_budget():
    pct, v = sweep_speed(SWEEP, 5.0)
    assert v * 0.005 <= SWEEP.max_blur_fraction * SWEEP.depth_of_field_mm
    assert (pct + 1) * SWEEP.line_speed_mm_s / 100 * 0.005 > SWEEP.max_blur_fraction * SWEEP.depth_of_field_mm
    assert (pct, v) == (10, 200.0)
    # A sim ten times faster runs the same real speed at a tenth of the program speed; the fine sweep is slower.
    assert sweep_speed(SWEEP, 5.0, time_scale=10.0) == (1, 200.0)
    assert sweep_speed(SWEEP, 5.0, factor=0.5)[1] == 100.0
    plan = plan_sweep(SWEEP, 5.0, 0.0, 40.0)
    assert (plan.from_mm, plan.to_mm, plan.speed_pct, plan.blur_mm) == (0.0, 40.0, 10, 1.0)


def test_an_exposure_too_long_for_the_budget_is_refused_before_anything_moves():
    with pytest.raises(ValueError, match="exposure_ms = 200 .*stepwise"):
        check_sweep(SWEEP, 200.0)
    with pytest.raises(ValueError, match="time_scale 20"):
        check_sweep(SWEEP, 5.0, time_scale=20.0)
    check_sweep(dataclasses.replace(SWEEP, mode="stepwise"), 200.0)  # the stepwise loop has no such limit


@pytest.mark.parametrize("z0", [17.7, 21.3, 23.45])
def test_fit_recovers_the_plane_between_frames(z0):
    z = np.arange(0.7, 40.0, 2.8)
    fit = fit_peak(z, curve(z, z0))
    assert fit.ok and fit.bracketed and fit.side == 0
    sharpest = z0 - 0.01 * 3.0 / math.sqrt(0.25**2 - 0.01**2)  # the skew moves the sharpest place off z0
    assert fit.peak_mm == pytest.approx(sharpest, abs=1e-3) and fit.sigma_mm < 1e-3
    assert fit.window_mm[0] < z0 < fit.window_mm[1] and fit.n_points >= 7


def test_uncertainty_grows_with_the_scatter_and_covers_the_error():
    z = np.arange(0.7, 40.0, 2.8)
    errors, sigmas = [], []
    for seed in range(30):
        fit = fit_peak(z, curve(z, 21.3, noise=0.02, seed=seed))
        errors.append(fit.peak_mm - fit_peak(z, curve(z, 21.3)).peak_mm)
        sigmas.append(fit.sigma_mm)
    rms = math.sqrt(float(np.mean(np.square(errors))))
    assert 0.5 * rms < float(np.median(sigmas)) < 2.5 * rms  # the stated sigma is the error's size
    assert float(np.median(sigmas)) > fit_peak(z, curve(z, 21.3, noise=0.005, seed=1)).sigma_mm


def test_a_peak_at_an_end_of_the_sweep_is_not_bracketed_and_says_which_end():
    z = np.arange(0.0, 22.0, 2.0)
    far = fit_peak(z, curve(z, 30.0))
    assert not far.bracketed and far.side == 1
    near = fit_peak(z + 25.0, curve(z + 25.0, 22.0))
    assert not near.bracketed and near.side == -1


def test_too_few_frames_is_no_fit():
    z = np.arange(0.0, 40.0, 8.0)
    fit = fit_peak(z, curve(z))
    assert not fit.ok and "frames" in fit.why and math.isinf(fit.sigma_mm)
    assert not fit_peak([1.0, 2.0], [3.0, 4.0]).ok


def test_clock_offset_is_zero_when_the_clocks_agree_else_the_nearer_bound():
    assert clock_offset(-0.002, 0.001) == 0.0
    assert clock_offset(0.010, 0.012) == 0.010
    assert clock_offset(-0.012, -0.010) == -0.010
    assert clock_offset(0.003, 0.001) == pytest.approx(0.002)  # inconsistent bounds: their middle


def test_state_track_interpolates_on_one_clock_and_shifts_a_sender_ahead():
    tr = StateTrack()
    for k in range(5):  # received 2 ms (and once 1 ms) after the sender's time: one clock, offset 0
        tr.add(100.0 + 0.01 * k, 100.0 + 0.01 * k + (0.001 if k == 2 else 0.002), 2.0 * k)
    assert tr.delay_s == pytest.approx(0.001) and tr.offset_s == 0.0
    assert tr.at(100.015) == pytest.approx(3.0)  # halfway between 2 mm and 4 mm
    assert math.isnan(tr.at(99.0)) and math.isnan(tr.at(101.0))
    assert tr.covers(100.04) and not tr.covers(100.041)
    tr.add(100.0, 100.1, 99.0)  # out of order: ignored
    assert len(tr) == 5
    ahead = StateTrack()  # the sender's clock 50 ms ahead: samples "arrive before they were taken"
    for k in range(5):
        ahead.add(100.05 + 0.01 * k, 100.0 + 0.01 * k + 0.002, 2.0 * k)
    assert ahead.offset_s == pytest.approx(-0.048)
    assert ahead.at(100.017) == pytest.approx(3.0)


def test_planned_profile_is_a_trapezoid_between_the_acks():
    t0, t1, ramp = 10.0, 10.3, 0.1  # 40 mm: cruise 200 mm/s for 0.1 s between two 0.1 s ramps
    assert profile_offset(9.0, t0, t1, 0.0, 40.0, ramp) == 0.0
    assert profile_offset(11.0, t0, t1, 0.0, 40.0, ramp) == 40.0
    assert profile_offset(10.15, t0, t1, 0.0, 40.0, ramp) == pytest.approx(20.0)
    assert profile_offset(10.1, t0, t1, 0.0, 40.0, ramp) == pytest.approx(10.0)  # 0.5 * 200 mm/s * 0.1 s
    assert profile_offset(10.15, t0, t1, 40.0, 0.0, ramp) == pytest.approx(20.0)  # backwards alike


def test_cell_values_out_of_range_name_the_key():
    from aioadept.cell.config import CellConfig
    from aioadept.errors import ConfigError

    with pytest.raises(ConfigError, match=r"\[focus\].*max_blur_fraction = 0"):
        CellConfig.from_dict({"focus": {"max_blur_fraction": 0}})
    with pytest.raises(ConfigError, match=r"\[focus\].*mode = 'fast'"):
        CellConfig.from_dict({"focus": {"mode": "fast"}})
    assert CellConfig.from_dict({"focus": {"mode": "sweep", "frame_interval_s": 0.02}}).focus.frame_interval_s == 0.02


def test_next_sweep_extends_past_the_open_end_within_the_reach_and_the_fine_one_crosses_the_peak():
    from aioadept.errors import FocusError
    from aioadept.apps.sweep_plan import max_reach_mm, next_plan

    assert max_reach_mm(SWEEP) == 80.0  # max_steps x delta_z_mm, the stepwise loop's reach
    rising = PeakFit(40.0, math.inf, 3, (30.0, 40.0), False, 1)
    plan = next_plan(SWEEP, 5.0, rising, 40.0, 1.0)
    assert (plan.kind, plan.from_mm, plan.to_mm) == ("extend", 40.0, 60.0)
    assert next_plan(SWEEP, 5.0, rising, 70.0, 1.0).to_mm == 80.0  # capped at the reach
    with pytest.raises(FocusError, match="within 80 mm"):
        next_plan(SWEEP, 5.0, PeakFit(80.0, math.inf, 3, (70.0, 80.0), False, 1), 80.0, 1.0)
    behind = PeakFit(0.0, math.inf, 3, (0.0, 8.0), False, -1)
    assert next_plan(SWEEP, 5.0, behind, 40.0, 1.0).to_mm == -20.0  # back past the start, away from the camera
    uncertain = PeakFit(21.3, 0.3, 7, (12.0, 33.0), True, 0)
    fine = next_plan(SWEEP, 5.0, uncertain, 40.0, 1.0)
    assert (fine.kind, fine.from_mm, fine.to_mm, fine.speed_mm_s) == ("fine", 27.3, 15.3, 100.0)
    assert (next_plan(SWEEP, 5.0, uncertain, 0.0, 1.0).from_mm, next_plan(SWEEP, 5.0, uncertain, 0.0, 1.0).to_mm) \
        == (15.3, 27.3)
    forward = next_plan(SWEEP, 5.0, uncertain, 40.0, 1.0, forward_only=True)
    assert (forward.from_mm, forward.to_mm) == (15.3, 27.3)


def test_a_fine_sweep_that_left_too_few_frames_on_the_peak_is_followed_by_a_slower_one():
    from aioadept.apps.sweep_plan import next_plan, sweep_speed

    fastest = sweep_speed(SWEEP, 5.0)[1]
    short = PeakFit(21.3, math.inf, 5, (18.0, 24.0), True, 0, ok=False, why="5 frames on the peak")
    first = next_plan(SWEEP, 5.0, short, 40.0, 1.0)  # after the coarse sweep: the configured fine speed
    assert first.kind == "fine" and first.speed_mm_s == pytest.approx(fastest * SWEEP.fine_speed_factor)
    second = next_plan(SWEEP, 5.0, short, first.to_mm, 1.0, last=first)  # 5 of the 7 needed: 5/8 of the speed
    assert second.kind == "fine" and first.speed_mm_s * 0.55 < second.speed_mm_s <= first.speed_mm_s * 5 / 8
    enough = PeakFit(21.3, 0.3, 9, (15.0, 27.0), True, 0)  # frames enough, the peak uncertain: the same speed
    assert next_plan(SWEEP, 5.0, enough, first.to_mm, 1.0, last=first).speed_mm_s == first.speed_mm_s
    none = PeakFit(21.3, math.inf, 0, (21.3, 21.3), True, 0, ok=False)  # nothing on the peak: a quarter (whole %)
    assert next_plan(SWEEP, 5.0, none, 40.0, 1.0, last=first).speed_pct == first.speed_pct // 4 == 1
    crawl = dataclasses.replace(first, speed_mm_s=SWEEP.line_speed_mm_s / 100)
    assert next_plan(SWEEP, 5.0, short, 40.0, 1.0, last=crawl).speed_pct == 1  # never below 1 % program speed


def test_the_sweep_figure_shows_frames_fit_and_plane(tmp_path):
    pytest.importorskip("matplotlib")
    from aioadept.analysis.plots import plot_sweep

    z = np.arange(0.7, 40.0, 2.8)
    s = curve(z)
    fit = fit_peak(z, s)
    result = {"peak_offset_mm": fit.peak_mm, "peak_sigma_mm": fit.sigma_mm, "pose_source": "state-stream",
              "frames": [{"sweep": 0, "offset_mm": float(a), "sharpness": float(b)} for a, b in zip(z, s, strict=True)],
              "sweep": {"plans": [{"kind": "coarse", "speed_mm_s": 200.0}], "fits": [fit.as_dict()]}}
    path = plot_sweep(result, tmp_path / "fig09b_sweep.png")
    assert path.stat().st_size > 10_000 and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert np.allclose(fit.sharpness_at(z[3:8]), s[3:8], rtol=1e-3)  # the curve drawn is the one fitted


def test_a_fit_logs_as_one_readable_line():
    good = PeakFit(19.518, 0.2687, 8, (15.3, 27.3), True, model="m", params=(1.0,), scale=2.0)
    assert good.summary() == "peak 19.52 +- 0.269 mm from 8 frames, bracketed"
    rising = PeakFit(40.0, math.inf, 3, (30.0, 40.0), False, 1)
    assert rising.summary().endswith("not bracketed (rising at the far end)")
    failed = PeakFit(math.nan, math.inf, 6, (math.nan, math.nan), False, ok=False, why="6 frames")
    assert failed.summary() == "no peak: 6 frames"
