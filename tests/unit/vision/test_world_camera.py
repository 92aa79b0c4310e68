"""The world's camera: cv2.aruco detects every rendered marker where the world puts it (through the noise and the
lens blur), each part is drawn at its projected place, a grasped part moves in the image, and the source delivers
mono8 frames like the other cameras."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from aioadept.geometry import Pose
from aioadept.world import World
from aioadept.vision.world_camera import TABLE_GREY, WorldCameraSource, WorldView
from aioadept.world import Feeder, PartSpec, WorldCamera, WorldConfig


def config(**camera) -> WorldConfig:
    parts = (PartSpec(1, "box", (40, 30, 20), (200, 40, 40), marker=3, marker_mm=18, x_mm=420, y_mm=60, yaw_deg=25),
             PartSpec(2, "cylinder", (36, 36, 30), (40, 70, 200), marker=7, marker_mm=18, x_mm=500, y_mm=-80),
             PartSpec(3, "box", (50, 50, 10), (40, 160, 60), marker=11, marker_mm=25, x_mm=380, y_mm=-60,
                      yaw_deg=-70),
             PartSpec(4, "box", (30, 30, 30), (230, 200, 40), x_mm=540, y_mm=90))      # no marker
    cam = dict(x_mm=450.0, y_mm=0.0, z_mm=900.0, focal_length_mm=8.0, f_number=8.0)
    cam.update(camera)
    return WorldConfig(table_z_mm=5.0, parts=parts, feeder=Feeder(420, 60), camera=WorldCamera(**cam))


def detect(image: np.ndarray, world: WorldConfig) -> dict[int, np.ndarray]:
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, world.aruco_dict))
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    corners, ids, _ = cv2.aruco.ArucoDetector(dictionary, params).detectMarkers(image)
    return {} if ids is None else {int(i): c.reshape(4, 2) for i, c in zip(ids.ravel(), corners, strict=True)}


@pytest.mark.parametrize("camera", [{}, {"yaw_deg": 30.0, "x_mm": 420.0, "y_mm": 40.0}, {"noise_sigma": 6.0}])
def test_aruco_finds_every_marker_where_the_world_puts_it(camera):
    cfg = config(**camera)
    world = World(cfg)
    view = WorldView(cfg, seed=1)
    snap = world.snapshot(0.0)
    image = view.render(snap.parts)
    assert image.dtype == np.uint8 and image.shape == (cfg.camera.height_px, cfg.camera.width_px)
    found = detect(image, cfg)
    assert sorted(found) == [3, 7, 11], "each marker once, and nothing else"
    for spec in cfg.parts:
        if spec.marker is None:
            continue
        want = view.project(view.marker_corners_mm(spec, snap.part(spec.id)))
        err = np.abs(found[spec.marker] - want).max()
        assert err < 0.75, f"marker {spec.marker}: corners {err:.2f} px from where the world puts them"


def test_parts_are_drawn_at_their_projected_place_and_a_grasped_part_moves():
    cfg = config(noise_sigma=0.0)
    world = World(cfg)
    view = WorldView(cfg)
    before = view.render_colour(world.snapshot(0.0).parts)
    # the yellow box (no marker): its top centre is yellow, the table around it grey
    spec = cfg.part(4)
    centre = view.project(np.array([[spec.x_mm, spec.y_mm, cfg.table_z_mm + spec.height_mm]]))[0]
    u, v = (int(round(c)) for c in centre)
    assert tuple(before[v, u]) == (40, 200, 230)                  # BGR of RGB (230, 200, 40)
    # grasp it, lift it, carry it 100 mm along world -y: it leaves its place and appears there
    tcp = Pose(spec.x_mm, spec.y_mm, cfg.table_z_mm + 15.0, 0.0, 180.0, 0.0)
    assert world.hand_closed(1.0, tcp)[0].part == 4
    moved = Pose(spec.x_mm, spec.y_mm - 100.0, cfg.table_z_mm + 115.0, 0.0, 180.0, 0.0)
    after = view.render_colour(world.snapshot(2.0, moved).parts)
    assert tuple(after[v, u]) == TABLE_GREY
    centre2 = view.project(np.array([[spec.x_mm, spec.y_mm - 100.0, cfg.table_z_mm + 130.0]]))[0]
    u2, v2 = (int(round(c)) for c in centre2)
    assert tuple(after[v2, u2]) == (40, 200, 230)


def test_the_source_delivers_mono8_frames_numbered_and_stamped():
    cfg = config()
    t = [100.0]
    source = WorldCameraSource(WorldView(cfg, seed=2), lambda: None, clock=lambda: t[0], sleep=None)
    f0, f1 = source.grab(), source.grab()
    assert (f0.seq, f1.seq) == (0, 1) and f0.t_s == 100.0 and f0.camera_id == "world"
    assert f0.image.dtype == np.uint8 and f0.image.ndim == 2
    assert sorted(detect(f0.image, cfg)) == [3, 7, 11], "before any world state: the parts where the file puts them"


def test_a_world_without_a_camera_is_refused():
    with pytest.raises(ValueError, match="camera"):
        WorldView(WorldConfig())


def test_frames_carry_the_age_of_the_world_state_they_show():
    from aioadept.vision.world_camera import WorldStateFollower

    t = [50.0]
    follower = WorldStateFollower("tcp://127.0.0.1:1", clock=lambda: t[0])   # never started: nothing received
    source = WorldCameraSource(WorldView(config(), seed=3), follower.parts, state_age=follower.state_age_s,
                               clock=lambda: t[0], sleep=None)
    assert source.grab().pose_age_s == float("inf"), "no world state yet: the node's max_state_age refuses it"
    follower.received_t = 49.8
    assert source.grab().pose_age_s == pytest.approx(0.2)
