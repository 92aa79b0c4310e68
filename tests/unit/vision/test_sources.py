"""Image folder replay, frame recording, OpenCV capture from a video file."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from aioadept.errors import VisionError
from aioadept.vision.sources import Frame, FrameRecorder, ImageFolderSource, OpenCVSource, to_mono8


def _img(value: int, shape=(24, 32)) -> np.ndarray:
    return np.full(shape, value, np.uint8)


def test_recorder_and_folder_replay_round_trip_with_recorded_times(tmp_path):
    rec = FrameRecorder(tmp_path)
    for i, t in enumerate([5.25, 5.5, 6.0]):
        rec.write(Frame(_img(10 * i), t, "cam:0", i))
    rec.close()
    src = ImageFolderSource(tmp_path, timestamps_csv=tmp_path / "frames.csv", camera_id="replay")
    frames = [src.grab() for _ in range(3)]
    assert [f.t_s for f in frames] == [5.25, 5.5, 6.0]
    assert [int(f.image[0, 0]) for f in frames] == [0, 10, 20] and [f.seq for f in frames] == [0, 1, 2]
    assert frames[0].camera_id == "replay" and frames[0].image.shape == (24, 32)
    assert src.grab() is None  # exhausted


def test_folder_in_name_order_stamped_at_grab_time_and_looping(tmp_path):
    for name, v in [("b.png", 2), ("a.png", 1), ("c.jpg", 3), ("notes.txt", 0)]:
        if name.endswith("txt"):
            (tmp_path / name).write_text("x")
        else:
            cv2.imwrite(str(tmp_path / name), cv2.cvtColor(_img(v * 50), cv2.COLOR_GRAY2BGR))
    clock = iter(range(100, 200))
    src = ImageFolderSource(tmp_path, loop=True, clock=lambda: float(next(clock)))
    assert len(src) == 3
    frames = [src.grab() for _ in range(4)]
    assert [abs(int(f.image.mean()) - v) <= 2 for f, v in zip(frames, [50, 100, 150, 50], strict=True)] == [True] * 4
    assert [f.t_s for f in frames] == [100.0, 101.0, 102.0, 103.0] and frames[3].seq == 3
    assert frames[0].image.ndim == 2


def test_folder_errors(tmp_path):
    with pytest.raises(VisionError, match="does not exist"):
        ImageFolderSource(tmp_path / "nope")
    with pytest.raises(VisionError, match="no images"):
        ImageFolderSource(tmp_path)
    (tmp_path / "bad.csv").write_text("name,time\nx.png,1\n")
    with pytest.raises(VisionError, match="columns"):
        ImageFolderSource(tmp_path, timestamps_csv=tmp_path / "bad.csv")


def test_opencv_source_reads_a_video_file_as_mono8(tmp_path):
    path = str(tmp_path / "v.avi")
    w = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48))
    for i in range(4):
        w.write(np.full((48, 64, 3), 40 * (i + 1), np.uint8))
    w.release()
    with OpenCVSource(path) as src:
        frames = []
        while (f := src.grab()) is not None:
            frames.append(f)
    assert len(frames) == 4 and [f.seq for f in frames] == [0, 1, 2, 3]
    assert all(f.image.shape == (48, 64) and f.image.dtype == np.uint8 for f in frames)
    assert [round(float(f.image.mean()) / 40) for f in frames] == [1, 2, 3, 4]
    assert frames[0].t_s <= frames[-1].t_s and frames[0].camera_id == f"opencv:{path}"


def test_opencv_source_that_cannot_open():
    with pytest.raises(VisionError, match="cannot open"):
        OpenCVSource("/nonexistent/video.avi")


def test_to_mono8_layouts():
    assert to_mono8(np.full((2, 2, 4), 7, np.uint8)).shape == (2, 2)
    assert to_mono8(np.full((2, 2), 0x1200, np.uint16)).tolist() == [[0x12, 0x12], [0x12, 0x12]]
    with pytest.raises(VisionError):
        to_mono8(np.zeros((2, 2), np.float32))
