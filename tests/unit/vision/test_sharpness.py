"""The eight sharpness steps on small synthetic images, and the assembled graph."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from aioadept.errors import GraphError, ObjectNotFound, VisionError
from aioadept.vision import sharpness as S


def plate_image(*, blur_sigma: float = 0.0, w: int = 320, h: int = 240, noise: float = 0.0, seed: int = 0):
    """A small version of the calibration object: 150 x 100 px white plate, three nested black outlines."""
    img = np.full((h, w), 20, np.uint8)
    x0, y0 = (w - 150) // 2, (h - 100) // 2
    img[y0:y0 + 100, x0:x0 + 150] = 225
    for inset in (12, 24, 36):
        cv2.rectangle(img, (x0 + inset, y0 + inset), (x0 + 149 - inset, y0 + 99 - inset), 30, 2)
    if blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_sigma)
    if noise > 0:
        rng = np.random.default_rng(seed)
        img = np.clip(img + rng.normal(0, noise, img.shape), 0, 255).astype(np.uint8)
    return img


SMALL = dict(threshold=128, erosion_kernel_px=3, erosion_iterations=1, wh_ratio_range=(1.2, 1.9),
             min_area_px=2000, roi_margin_px=4, sobel_ksize=3)


def test_highlight_light_keeps_pixels_strictly_above_threshold():
    img = np.array([[0, 127, 128, 129, 255]], np.uint8)
    assert S.highlight_light(img, 128).tolist() == [[0, 0, 0, 255, 255]]
    with pytest.raises(VisionError, match="mono8"):
        S.highlight_light(np.zeros((4, 4, 3), np.uint8), 128)


def test_erosion_removes_speckles_and_shrinks_blobs():
    m = np.zeros((40, 40), np.uint8)
    m[5, 5] = 255                      # a one-pixel speckle
    m[10:30, 10:30] = 255              # a 20 x 20 blob
    out = S.erosion(m, 3, 2)
    assert out[5, 5] == 0
    ys, xs = np.nonzero(out)
    assert (ys.min(), ys.max(), xs.min(), xs.max()) == (12, 27, 12, 27)  # 2 iterations x 1 px per side


def test_find_ccomp_boxes_and_enclosed_area():
    m = np.zeros((60, 100), np.uint8)
    m[10:20, 10:40] = 255                                     # solid 30 x 10
    cv2.rectangle(m, (50, 5), (89, 54), 255, 1)               # an outline 40 x 50 (a ring with a hole)
    cc = S.find_ccomp(m)
    assert cc.count == 2
    rows = sorted(tuple(int(v) for v in r) for r in cc.stats)
    assert rows[0][:4] == (10, 10, 30, 10)
    assert rows[1][:4] == (50, 5, 40, 50)
    assert rows[1][4] == 39 * 49  # the ring's enclosed area, hole included


def test_identify_object_region_filters_by_ratio_and_area_and_takes_the_largest():
    m = np.zeros((200, 300), np.uint8)
    m[10:50, 10:70] = 255      # 60 x 40: ratio 1.5, area 2400
    m[60:160, 100:250] = 255   # 150 x 100: ratio 1.5, area 15000 -> the object
    m[10:190, 270:290] = 255   # 20 x 180: wrong ratio, large
    cc = S.find_ccomp(m)
    r = S.identify_object_region(cc, (1.2, 1.9), 1000)
    assert (r.x_px, r.y_px, r.width_px, r.height_px) == (100, 60, 150, 100)
    r_small_only = S.identify_object_region(cc, (1.4, 1.6), 1000)
    assert r_small_only.width_px == 150
    with pytest.raises(ObjectNotFound, match="no object found: none of 3 light regions") as info:
        S.identify_object_region(cc, (1.2, 1.9), 20_000)
    assert isinstance(info.value, VisionError) and info.value.attributes == {"n_regions": 3}


def test_crop_roi_applies_the_margin_and_rejects_tiny_regions():
    img = np.arange(100 * 100, dtype=np.uint32).reshape(100, 100)
    roi = S.crop_roi(img, S.Region(10, 20, 30, 40), 5)
    assert roi.shape == (30, 20) and roi[0, 0] == img[25, 15] and roi[-1, -1] == img[54, 34]
    with pytest.raises(ObjectNotFound, match="too small"):
        S.crop_roi(img, S.Region(0, 0, 10, 10), 5)


def test_sobel_x_responds_to_vertical_edges_only():
    img = np.zeros((20, 20), np.uint8)
    img[:, 10:] = 200          # vertical edge between columns 9 and 10
    gx = S.sobel_x(img, 3)
    assert gx.dtype == np.float32
    assert np.all(gx[:, 9] == 800) and np.all(gx[:, 10] == 800) and np.count_nonzero(gx) == 40
    horiz = np.zeros((20, 20), np.uint8)
    horiz[10:, :] = 200
    assert np.count_nonzero(S.sobel_x(horiz, 3)) == 0


def test_h_profile_is_the_middle_row_and_sharpness_its_std():
    im = np.arange(5 * 4, dtype=np.float32).reshape(5, 4)
    prof = S.h_profile_sobelx(im)
    assert prof.tolist() == [8, 9, 10, 11]
    assert S.measure_sharpness(prof) == pytest.approx(np.std([8, 9, 10, 11]))
    assert S.measure_sharpness(np.zeros(7, np.float32)) == 0.0


def test_graph_tokens_follow_the_paper():
    g = S.sharpness_graph()
    assert g.order == ("highlight_light", "erosion", "find_ccomp", "identify_object_region", "crop_roi", "sobel_x",
                       "h_profile_sobelx", "measure_sharpness")
    assert g.free_tokens == ("image",) and g.output_tokens == ("sharpness",)
    assert set(g.frozen_tokens) == set(S.DEFAULT_HYPERPARAMETERS)
    assert S.sharpness_graph(threshold=100).frozen_tokens["threshold"] == 100
    with pytest.raises(GraphError):
        S.sharpness_graph(thresh=100)


def test_sharper_images_measure_sharper():
    g = S.sharpness_graph(**SMALL)
    values = [g.run(image=plate_image(blur_sigma=s, noise=2.0))["sharpness"] for s in (0.0, 1.0, 2.0, 4.0)]
    assert values == sorted(values, reverse=True)
    assert values[0] > 3 * values[-1]


def test_graph_run_exposes_fig8_tokens():
    run = S.sharpness_graph(**SMALL).run(image=plate_image())
    region = run["object_region"]
    # The plate is 150 x 100; one erosion iteration takes 1 px off each side, the margin 4 px more.
    assert (region.x_px, region.y_px, region.width_px, region.height_px) == (86, 71, 148, 98)
    assert run["sobelx_im"].shape == (98 - 8, 148 - 8)
    assert run["profile_sx"].shape == (148 - 8,)


def test_no_object_is_an_error_result_not_nan():
    blank = np.full((240, 320), 20, np.uint8)
    res = S.measure(blank, S.sharpness_graph(**SMALL))
    assert not res.ok and res.sharpness is None and res.error.startswith("no object found")
    ok = S.measure(plate_image(), S.sharpness_graph(**SMALL))
    assert ok.ok and ok.sharpness > 0 and ok.region is not None and ok.proc_time_ms > 0
    assert list(ok.node_time_ms) == list(S.sharpness_graph().order)


def test_default_graph_on_a_full_frame_plate():
    # The default hyperparameters are tuned for the 1024 x 768 virtual camera: a scaled-up plate must pass.
    img = cv2.resize(plate_image(), (1024, 768), interpolation=cv2.INTER_NEAREST)
    res = S.measure(img)
    assert res.ok and res.region.width_px == pytest.approx(150 * 3.2, abs=4)
