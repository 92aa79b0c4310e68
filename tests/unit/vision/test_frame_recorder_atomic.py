"""Saved frames appear whole: a reader following the folder (the run recorder) never reads half a PNG."""

from __future__ import annotations

import threading

import cv2
import numpy as np

from aioadept.vision.sources import Frame, FrameRecorder


def test_a_reader_polling_the_folder_never_sees_a_partial_png(tmp_path):
    rec = FrameRecorder(tmp_path)
    rng = np.random.default_rng(1)
    image = rng.integers(0, 255, (480, 640), dtype=np.uint8)  # noise: large PNGs, slow to write
    bad: list[str] = []
    done = threading.Event()

    def follow() -> None:
        seen: set[str] = set()
        while not done.is_set():
            for p in tmp_path.glob("*.png"):
                if p.name.startswith(".") or p.name in seen:
                    continue
                if cv2.imread(str(p), cv2.IMREAD_UNCHANGED) is None:
                    bad.append(p.name)
                seen.add(p.name)

    reader = threading.Thread(target=follow)
    reader.start()
    try:
        for seq in range(1, 41):
            rec.write(Frame(image=image, t_s=1000.0 + seq, camera_id="cam0", seq=seq))
    finally:
        done.set()
        reader.join(timeout=10)
        rec.close()
    assert bad == []
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [f"cam0_{i:06d}.png" for i in range(1, 41)]
    assert not list(tmp_path.glob(".*")), "temporary files left behind"
    assert len((tmp_path / "frames.csv").read_text().splitlines()) == 41
