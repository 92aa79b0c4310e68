"""Camera sources behind one interface: ``grab() -> Frame``.

The acquisition service (:mod:`aioadept.vision.acquisition`) calls ``grab()`` from one thread per source and keeps
the frames in a ring buffer. A source here:

- :class:`ImageFolderSource` replays image files (sorted by name), timestamped at grab time or from a CSV;
- :class:`OpenCVSource` wraps ``cv2.VideoCapture``: a USB camera index, a video file or a stream URL;
- :class:`aioadept.vision.virtual_camera.VirtualCamera` renders the calibration object on the simulated robot.

Every frame is mono8 (``uint8``, 2-D) and stamped with ``time.time()`` epoch seconds (the clock that crosses
processes, docs/interfaces.md). ``grab()`` returns ``None`` when the source has no more frames (end of a file or a
folder); it may block until the next frame (a real camera), and sources pace nothing themselves: the acquisition
loop does.
"""

from __future__ import annotations

import abc
import contextlib
import csv
import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from aioadept.errors import VisionError

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")


@dataclass(frozen=True, slots=True, eq=False)
class Frame:
    """One image: ``image`` mono8 (H x W ``uint8``), ``t_s`` epoch seconds of exposure, source id, sequence number
    (0, 1, 2, ... per source, so gaps show dropped frames). ``pose_age_s``: for a frame rendered from a robot pose
    (the virtual camera), how long before ``t_s`` the newest robot state sample arrived (0 when a sample at or
    after ``t_s`` was there, ``inf`` with none at all); None for a real camera."""

    image: np.ndarray
    t_s: float
    camera_id: str
    seq: int
    pose_age_s: float | None = None
    exposure_s: float = 0.0
    """How long the sensor integrated, from ``t_s`` (the exposure start); 0 when the source does not say."""
    readout_s: float = 0.0
    """From the end of the exposure until the frame was in memory (sensor readout + GigE transfer)."""
    t_trigger: float | None = None
    """Epoch s of the software trigger that took this frame; None for a free-running grab."""


class Camera(abc.ABC):
    """The interface every source implements. Use as a context manager or call :meth:`close`.

    ``can_trigger``: the source takes a frame when asked (a software trigger: a virtual or GenICam camera), so a
    request can trigger its own exposure; sources that cannot (video files, webcams, folders) run free.
    """

    camera_id: str
    can_trigger: bool = False
    stop_wait_s: float | None = None
    """How long :meth:`Acquisition.stop <aioadept.vision.acquisition.Acquisition.stop>` waits for a grab in
    progress before it stops without it (the grabbing thread is then a daemon, and :meth:`close` must be safe
    under it). None: as long as the grab takes (closing an OpenCV capture under a reading thread is not safe)."""

    @abc.abstractmethod
    def grab(self) -> Frame | None:
        """The next frame, or ``None`` when the source is exhausted. May block until a frame is available."""

    def close(self) -> None:
        """Release the device or files. Idempotent. This default, for a source that holds nothing, does nothing."""
        return None

    def __enter__(self) -> Camera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def to_mono8(image: np.ndarray) -> np.ndarray:
    """Convert an OpenCV image (grey or BGR/BGRA, 8 or 16 bit) to mono8; raises VisionError for other layouts."""
    if image.dtype == np.uint16:
        image = (image >> 8).astype(np.uint8)
    elif image.dtype != np.uint8:
        raise VisionError(f"unsupported image dtype {image.dtype}")
    if image.ndim == 2:
        return image
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.ndim == 3 and image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2GRAY)
    if image.ndim == 3 and image.shape[2] == 1:
        return image[:, :, 0]
    raise VisionError(f"unsupported image shape {image.shape}")


class ImageFolderSource(Camera):
    """Replay the images of a folder in file-name order.

    Timestamps: with ``timestamps_csv`` (columns ``file,t_s``; the format :class:`FrameRecorder` writes) each frame
    carries its recorded time and only the files listed are replayed, in the CSV's order; without it each frame is
    stamped ``time.time()`` when grabbed, so a replay answers live requests. ``loop=True`` starts over at the end
    (the recorded timestamps then repeat, so use it with grab-time stamps).
    """

    def __init__(self, folder: str | os.PathLike[str], *, camera_id: str = "folder",
                 timestamps_csv: str | os.PathLike[str] | None = None, loop: bool = False,
                 clock: Callable[[], float] = time.time) -> None:
        self.folder = Path(folder)
        self.camera_id = camera_id
        self.loop = loop
        self._clock = clock
        self._seq = 0
        self._index = 0
        if timestamps_csv is not None:
            with open(timestamps_csv, newline="") as fh:
                rows = [r for r in csv.DictReader(fh)]
            try:
                self._files = [self.folder / r["file"] for r in rows]
                self._times: list[float] | None = [float(r["t_s"]) for r in rows]
            except KeyError as exc:
                raise VisionError(f"{timestamps_csv}: expected columns 'file' and 't_s'") from exc
        else:
            if not self.folder.is_dir():
                raise VisionError(f"image folder {self.folder} does not exist")
            self._files = sorted(p for p in self.folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
            self._times = None
        if not self._files:
            raise VisionError(f"no images in {self.folder}")

    def __len__(self) -> int:
        return len(self._files)

    def grab(self) -> Frame | None:
        if self._index >= len(self._files):
            if not self.loop:
                return None
            self._index = 0
        i = self._index
        self._index += 1
        image = cv2.imread(str(self._files[i]), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise VisionError(f"cannot read image {self._files[i]}")
        t_s = self._times[i] if self._times is not None else self._clock()
        frame = Frame(to_mono8(image), t_s, self.camera_id, self._seq)
        self._seq += 1
        return frame


class OpenCVSource(Camera):
    """A ``cv2.VideoCapture``: ``spec`` is a device index (``"0"`` or ``0``), a video file path, or a stream URL.

    Frames are stamped with ``time.time()`` right after ``read()`` returns. A failed read is the end of the stream
    (``None``). Raises :class:`VisionError` when the capture cannot be opened.
    """

    def __init__(self, spec: str | int, *, camera_id: str | None = None, width_px: int | None = None,
                 height_px: int | None = None) -> None:
        target: str | int = int(spec) if isinstance(spec, str) and spec.isdigit() else spec
        self.camera_id = camera_id or f"opencv:{spec}"
        self._cap = cv2.VideoCapture(target)
        if not self._cap.isOpened():
            self._cap.release()
            raise VisionError(f"cannot open video capture {spec!r}")
        if width_px:
            self._cap.set(cv2.CAP_PROP_FRAME_WIDTH, width_px)
        if height_px:
            self._cap.set(cv2.CAP_PROP_FRAME_HEIGHT, height_px)
        self._seq = 0
        self._closed = False

    def grab(self) -> Frame | None:
        if self._closed:
            return None
        ok, image = self._cap.read()
        t_s = time.time()
        if not ok or image is None:
            return None
        frame = Frame(to_mono8(image), t_s, self.camera_id, self._seq)
        self._seq += 1
        return frame

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._cap.release()


class FrameRecorder:
    """Write frames as PNG files plus ``frames.csv`` (``file,t_s,camera_id,seq``) into a folder, so that
    :class:`ImageFolderSource` with ``timestamps_csv`` replays them with their original times.

    Thread-safe enough for one writer per camera; files are named ``<camera_id>_<seq:06d>.png``. Nothing is left
    half written under its final name (a full disk left an empty ``frames.csv``): each PNG is
    renamed into place once whole, and ``frames.csv`` is written under a temporary name and renamed by
    :meth:`close` only if every row reached the disk (else it is removed, ``csv_error`` says why, and a
    ``frames.csv`` from before keeps its content). Its rows list the PNGs that were written.
    """

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self._csv_path = self.folder / "frames.csv"
        self._tmp_path = self.folder / f".frames.csv.{os.getpid()}.tmp"
        self.csv_error: str | None = None
        """Why ``frames.csv`` was not written (set by a failed write or :meth:`close`), else None."""
        self._fh = open(self._tmp_path, "w", newline="")
        try:
            self._writer = csv.writer(self._fh)
            if self._csv_path.exists():  # a second recorder into the same folder appends, as before
                self._fh.write(self._csv_path.read_text())
            else:
                self._writer.writerow(["file", "t_s", "camera_id", "seq"])
        except BaseException:
            self._fh.close()
            with contextlib.suppress(OSError):
                os.unlink(self._tmp_path)
            raise

    def write(self, frame: Frame) -> Path:
        name = f"{frame.camera_id.replace(':', '_').replace('/', '_')}_{frame.seq:06d}.png"
        path = self.folder / name
        # Written under a temporary name and renamed: a reader following the folder (the run recorder) never sees
        # half a PNG. The temporary name keeps the .png suffix, which tells OpenCV the format.
        tmp = self.folder / f".{name[:-4]}.tmp.png"
        try:
            if not cv2.imwrite(str(tmp), frame.image):
                raise VisionError(f"cannot write {path}")
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)  # a full disk leaves part of it
            raise
        if self.csv_error is None:
            try:
                self._writer.writerow([name, f"{frame.t_s:.6f}", frame.camera_id, frame.seq])
                self._fh.flush()
            except OSError as exc:
                self.csv_error = exc.strerror or str(exc)
        return path

    def close(self) -> None:
        """Finish ``frames.csv``: renamed into place when every row was written, else removed (``csv_error``)."""
        if self._fh.closed:
            return
        try:
            if self.csv_error is None:
                self._fh.flush()
                os.fsync(self._fh.fileno())
        except OSError as exc:
            self.csv_error = exc.strerror or str(exc)
        finally:
            with contextlib.suppress(OSError):  # the error, if any, was already met by the flush above
                self._fh.close()
        try:
            if self.csv_error is None:
                os.replace(self._tmp_path, self._csv_path)
                return
        except OSError as exc:
            self.csv_error = exc.strerror or str(exc)
        with contextlib.suppress(OSError):
            os.unlink(self._tmp_path)
        log.error("%s not written: %s", self._csv_path, self.csv_error)
