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


def test_a_frames_csv_the_disk_cannot_take_is_not_left_under_its_name(tmp_path):
    # A full disk must not leave an empty frames.csv under its name. A real write error: a child process with a
    # file-size limit (RLIMIT_FSIZE binds root too; Python ignores SIGXFSZ, so the write fails with EFBIG). The
    # 200 rows need ~8 KiB, over the 2 KiB limit; each tiny PNG fits.
    import subprocess
    import sys

    script = (
        "import resource, sys, numpy as np\n"
        "from aioadept.vision.sources import Frame, FrameRecorder\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (2048, 2048))\n"
        "rec = FrameRecorder(sys.argv[1])\n"
        "for seq in range(200):\n"
        "    rec.write(Frame(image=np.zeros((8, 8), np.uint8), t_s=1000.0 + seq, camera_id='cam0', seq=seq))\n"
        "rec.close()\n"
        "print(rec.csv_error)\n")
    proc = subprocess.run([sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "File too large"
    assert not (tmp_path / "frames.csv").exists()  # not there rather than cut short
    assert not list(tmp_path.glob(".*")), "temporary files left behind"
    assert len(list(tmp_path.glob("cam0_*.png"))) == 200
    assert "frames.csv not written: File too large" in proc.stderr


def test_a_second_recorder_appends_to_the_frames_csv_of_the_first(tmp_path):
    for seqs in ((1, 2), (3,)):
        rec = FrameRecorder(tmp_path)
        for seq in seqs:
            rec.write(Frame(image=np.zeros((8, 8), np.uint8), t_s=1000.0 + seq, camera_id="cam0", seq=seq))
        rec.close()
    rows = (tmp_path / "frames.csv").read_text().splitlines()
    assert rows[0] == "file,t_s,camera_id,seq" and [r.split(",")[0] for r in rows[1:]] == [
        "cam0_000001.png", "cam0_000002.png", "cam0_000003.png"]
