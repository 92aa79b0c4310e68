"""The world camera draws the cell file's tool marker (``[world.tool_marker]``) at the robot's tool pose, where
``aioadept calibrate`` needs it: the locator's detector finds it at its projected corners, from the tool pose the
source's ``tool_at`` gives for the frame's time; facing away from the camera it is not drawn; the table is checked."""

from __future__ import annotations

import numpy as np
import pytest

from aioadept.errors import ConfigError
from aioadept.geometry import Pose
from aioadept.vision.locate import detect_markers
from aioadept.vision.world_camera import WorldCameraSource, WorldView, parts_at_rest
from aioadept.cell.world import world_from_table, world_to_table

TABLE = {"table_z_mm": 380.0, "aruco_dict": "DICT_4X4_250",
         "parts": [{"id": 1, "size_mm": [40, 30, 25], "marker": 1, "marker_mm": 20, "x_mm": 480.0, "y_mm": 150.0}],
         "camera": {"x_mm": 480.0, "y_mm": 100.0, "z_mm": 1100.0},
         "tool_marker": {"marker": 200, "marker_mm": 40.0, "offset_mm": 5.0}}


@pytest.mark.parametrize("tool", [Pose(480.0, 100.0, 680.0, 0.0, 180.0, 0.0),
                                  Pose(520.0, 60.0, 700.0, 30.0, 165.0, -40.0)])
def test_the_tool_marker_is_seen_where_the_tool_puts_it(tool):
    world = world_from_table(TABLE)
    assert world.tool_marker is not None and world.tool_marker.marker == 200
    view = WorldView(world, seed=3)
    src = WorldCameraSource(view, lambda: None, tool_at=lambda t: tool, sleep=None)
    found = {m.id: m.corners_px for m in detect_markers(src.grab().image, world.aruco_dict)}
    assert 200 in found
    want = view.project(view.tool_marker_corners_mm(tool))
    assert np.abs(found[200] - want).max() < 0.5


def test_no_tool_pose_or_a_marker_facing_away_draws_no_tool_marker():
    world = world_from_table(TABLE)
    view = WorldView(world, seed=3)
    up = Pose(480.0, 100.0, 680.0, 0.0, 0.0, 0.0)  # tool pointing up: the plate faces the table
    for tool_at in (None, lambda t: None, lambda t: up):
        src = WorldCameraSource(view, lambda: None, tool_at=tool_at, sleep=None)
        assert 200 not in {m.id for m in detect_markers(src.grab().image, world.aruco_dict)}
    assert view.render_colour(parts_at_rest(world)).shape == (768, 1024, 3)


def test_the_tool_marker_table_is_checked_and_written_back():
    world = world_from_table(TABLE)
    assert world_from_table(world_to_table(world)) == world
    for bad, words in [({"marker": 1}, "a part carries it too"), ({"marker": 250}, "0..249"),
                       ({"marker_mm": 40.0}, "marker missing"), ({"marker": 5, "marker_mm": 0.0}, "marker_mm"),
                       ({"marker": 5, "size": 3}, "size")]:
        with pytest.raises(ConfigError, match=words):
            world_from_table({**TABLE, "tool_marker": bad})
