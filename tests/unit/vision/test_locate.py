"""The part locator on synthetic views with known truth (aioadept.vision.synthetic: the sim's camera model, its
lens blur and sensor noise), and the locator node's answers to good and bad requests (no sockets)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aioadept.bus.located import parts_from_attributes
from aioadept.vision.calibration import CameraCalibration
from aioadept.vision.locate import locate, locate_graph
from aioadept.vision.locate_node import LocatorNode
from aioadept.vision.synthetic import SyntheticPart, render

CAL = CameraCalibration()  # the world camera's default: 900 mm above (450, 0), f 8 mm, 1024 x 768, 4.65 um pixels


def yaw_diff(a: float, b: float, period: float = 360.0) -> float:
    return abs((a - b + period / 2) % period - period / 2)


def random_parts(rng: np.random.Generator, n: int, **kw) -> list[SyntheticPart]:
    return [SyntheticPart(float(rng.uniform(300, 600)), float(rng.uniform(-130, 130)), float(rng.uniform(-180, 180)),
                          **kw) for _ in range(n)]


def test_marked_parts_are_located_within_1_mm_and_1_degree():
    rng = np.random.default_rng(21)
    graph = locate_graph(CAL, height_mm=20.0)
    worst_mm = worst_deg = 0.0
    for k in range(30):
        (truth,) = random_parts(rng, 1, size_mm=(40.0, 40.0, 20.0), marker=k % 50, marker_mm=15.0)
        res = locate(render(CAL, [truth], seed=k), graph)
        assert res.ok and len(res.parts) == 1, res
        (p,) = res.parts
        assert p.kind == "marker" and p.marker == truth.marker
        worst_mm = max(worst_mm, math.hypot(p.x_mm - truth.x_mm, p.y_mm - truth.y_mm))
        worst_deg = max(worst_deg, yaw_diff(p.yaw_deg, truth.yaw_deg))
        assert p.z_mm == pytest.approx(20.0)
    # measured over seeds 21-23: 0.04-0.09 mm and 0.55-0.64 deg at worst (docs/vision.md, Part locator)
    assert worst_mm <= 1.0 and worst_deg <= 1.0, (worst_mm, worst_deg)


def test_several_marked_and_coloured_parts_in_one_view():
    truth = [SyntheticPart(380.0, -90.0, 25.0, (40.0, 40.0, 20.0), (200, 40, 40), marker=3),
             SyntheticPart(520.0, 110.0, -140.0, (40.0, 40.0, 20.0), (200, 40, 40), marker=9),
             SyntheticPart(340.0, 120.0, 30.0, (50.0, 30.0, 20.0), (40, 160, 60)),
             SyntheticPart(560.0, -120.0, -60.0, (50.0, 30.0, 20.0), (40, 70, 200))]
    res = locate(render(CAL, truth, seed=4), locate_graph(CAL, height_mm=20.0, colours=("green", "blue", "red")))
    assert res.ok, res.error
    assert [(p.kind, p.marker, p.colour) for p in res.parts] == [
        ("marker", 3, "red"), ("marker", 9, "red"), ("colour", None, "blue"), ("colour", None, "green")]
    by = {(p.marker, p.colour): p for p in res.parts}
    for t, key in zip(truth, [(3, "red"), (9, "red"), (None, "green"), (None, "blue")], strict=True):
        p = by[key]
        assert math.hypot(p.x_mm - t.x_mm, p.y_mm - t.y_mm) <= 1.0
        # a box's yaw (no marker) is defined modulo 180 (along its longer side)
        assert yaw_diff(p.yaw_deg, t.yaw_deg, 360.0 if key[0] is not None else 180.0) <= 1.0
    blue = by[(None, "blue")]
    assert blue.length_mm == pytest.approx(50.0, abs=1.5) and blue.width_mm == pytest.approx(30.0, abs=1.5)


def test_unmarked_coloured_parts_within_1_mm_and_1_degree():
    rng = np.random.default_rng(7)
    graph = locate_graph(CAL, height_mm=30.0, colours=("orange",))
    for k in range(10):
        (t,) = random_parts(rng, 1, size_mm=(60.0, 35.0, 30.0), rgb=(235, 130, 30))
        res = locate(render(CAL, [t], seed=100 + k), graph)
        assert res.ok and len(res.parts) == 1, (k, res)
        (p,) = res.parts
        assert math.hypot(p.x_mm - t.x_mm, p.y_mm - t.y_mm) <= 1.0, (k, p, t)
        assert yaw_diff(p.yaw_deg, t.yaw_deg, 180.0) <= 1.0, (k, p, t)


def test_the_height_matters_and_the_locator_never_guesses_it_for_colours():
    t = SyntheticPart(560.0, 150.0, 10.0, (50.0, 30.0, 40.0), (40, 160, 60))
    img = render(CAL, [t], seed=1)
    res = locate(img, locate_graph(CAL, colours=("green",)))
    assert not res.ok and "height_mm" in res.error
    wrong = locate(img, locate_graph(CAL, colours=("green",), height_mm=0.0)).parts[0]
    right = locate(img, locate_graph(CAL, colours=("green",), height_mm=40.0)).parts[0]
    assert math.hypot(right.x_mm - t.x_mm, right.y_mm - t.y_mm) <= 1.0
    # a 40 mm height error, 200 mm off the optical axis, 900 mm camera: ~9 mm off
    assert math.hypot(wrong.x_mm - t.x_mm, wrong.y_mm - t.y_mm) > 5.0


def test_an_empty_table_gives_no_parts():
    res = locate(render(CAL, [], seed=2), locate_graph(CAL, height_mm=20.0, colours=("red", "green", "blue")))
    assert res.ok and res.parts == ()


class _NoAcquisition:
    camera_ids = ("synthetic",)
    triggered: dict = {}


def test_locator_node_filters_and_answers_bad_requests_with_an_error():
    truth = [SyntheticPart(400.0, 50.0, 15.0, marker=4), SyntheticPart(500.0, -60.0, -30.0, marker=8)]
    img = render(CAL, truth, seed=5)
    node = LocatorNode(_NoAcquisition(), CAL, hyperparameters={"height_mm": 20.0})
    out = node.analyse(img, {})
    assert [p.marker for p in parts_from_attributes(out)] == [4, 8]
    only = parts_from_attributes(node.analyse(img, {"marker": 8, "corners": 1}))
    assert [p.marker for p in only] == [8] and len(only[0].corners_px) == 8
    assert parts_from_attributes(node.analyse(img, {"marker": 5})) == ()
    for bad, word in [({"height_mm": float("nan")}, "height_mm"), ({"marker": -1}, "marker"),
                      ({"marker": "4"}, "marker"), ({"colour": "purple"}, "colour"), ({"marker_mm": 0.0}, "marker_mm"),
                      ({"corners": 2}, "corners")]:
        answer = node.analyse(img, bad)
        assert answer["error"].startswith("bad request: " + word), answer
        assert "parts" not in answer
    no_height = LocatorNode(_NoAcquisition(), CAL)
    assert no_height.analyse(img, {"colour": "red"})["error"].startswith("locating coloured parts needs")
    assert len(parts_from_attributes(no_height.analyse(img, {"colour": "red", "height_mm": 20.0}))) == 2
    # still usable after the bad ones
    assert [p.marker for p in parts_from_attributes(node.analyse(img, {}))] == [4, 8]
