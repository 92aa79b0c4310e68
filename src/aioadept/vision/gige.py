"""A real GenICam / GigE Vision camera through Aravis, software-triggered: one exposure per request.

Needs the optional ``[gige]`` extra (the ``aravis-python`` wheel, which ships libaravis and its typelib, and
PyGObject; docs/vision.md says which system packages PyGObject builds with). Without it, :class:`GigECamera` raises
:class:`~aioadept.errors.VisionError` saying what to install.

**Opened by address, never by discovery.** Aravis's usual ``Aravis.Camera.new(name)`` goes through the interface
list, whose update broadcasts a GVCP discovery on every network interface. This module instead disables the
``GigEVision`` interface (so no device-list update in this process can broadcast) and builds the device with
``Aravis.GvDevice.new(interface_address, device_address)``: unicast GVCP to the camera's address only. The local
interface address is the one the routing table picks for the camera (a connected UDP socket's own address: no
packet is sent), or given explicitly.

**Acquisition.** ``TriggerMode=On``, ``TriggerSource=Software``, ``ExposureTime`` and ``PixelFormat`` are set at
open; a small pool of Aravis buffers is pushed to the stream; each :meth:`GigECamera.grab` drains stale buffers,
sends the software trigger, pops the frame (with a timeout), copies it once into a numpy array (PyGObject hands the
bytes over as one copy; the buffer goes back to the pool at once) and converts it to mono8. Timeouts, incomplete
buffers (lost packets), a camera that stops answering and every Aravis ``GLib.Error`` become
:class:`~aioadept.errors.VisionError`, which the node answers as an error response.

**Timing** (host clock, ``time.time()`` epoch s): ``t_trigger`` just before the trigger command, ``t_s`` (exposure
start) when the camera acknowledged it (so at most one GVCP round trip late, plus the camera's trigger latency),
``exposure_s`` the camera's ``ExposureTime``, ``readout_s`` from the exposure's end until Aravis had the last packet
(the buffer's system timestamp): sensor readout + GigE transfer.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from typing import Any

import numpy as np

from aioadept.errors import VisionError
from aioadept.vision.sources import Camera, Frame, to_mono8

GVCP_PORT = 3956
PIXEL_FORMATS = ("Mono8", "Mono16", "BayerRG8", "BayerGR8", "BayerGB8", "BayerBG8")
"""Pixel formats this source converts to mono8 (Bayer through OpenCV's demosaic to grey)."""

_BAYER_TO_GRAY = {"BayerRG8": "COLOR_BayerRG2GRAY", "BayerGR8": "COLOR_BayerGR2GRAY",
                  "BayerGB8": "COLOR_BayerGB2GRAY", "BayerBG8": "COLOR_BayerBG2GRAY"}

_aravis_lock = threading.Lock()
log = logging.getLogger(__name__)


def load_aravis() -> Any:
    """The ``gi.repository.Aravis`` module with the GigE Vision interface disabled (no discovery broadcast).

    Raises VisionError naming the missing piece when the ``[gige]`` extra is not installed or cannot load.
    """
    with _aravis_lock:
        try:
            import aravis  # noqa: F401  (loads the wheel's libaravis and points GI_TYPELIB_PATH at its typelib)
            from gi.repository import Aravis
        except Exception as exc:  # ImportError, or gi's ValueError/ImportError when the typelib or libusb is missing
            raise VisionError(
                "GigE Vision source needs the [gige] extra: from a clone run 'make gige' (it installs the Debian "
                "packages PyGObject builds with, libgirepository1.0-dev libcairo2-dev pkg-config, and libusb-1.0-0 "
                "for libaravis, then the pinned aravis-python and PyGObject); pip install 'aioadept[gige]' alone "
                f"fails without those packages ({type(exc).__name__}: {exc})") from exc
        # Before any device-list update: nothing in this process may send a broadcast discovery.
        Aravis.disable_interface("GigEVision")
        return Aravis


def local_address_for(device_address: str) -> str:
    """The local address the routing table uses to reach ``device_address`` (a UDP connect sends nothing)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect((device_address, GVCP_PORT))
        except OSError as exc:
            raise VisionError(f"no route to GigE camera {device_address}: {exc}") from exc
        return s.getsockname()[0]


def _check_ipv4(address: str, what: str) -> str:
    try:
        socket.inet_pton(socket.AF_INET, address)
    except OSError:
        raise VisionError(f"{what} must be an IPv4 address (GigE cameras are opened by address, never by "
                          f"discovery), got {address!r}") from None
    return address


class GigECamera(Camera):
    """A GigE Vision camera at ``address`` (IPv4), software-triggered, each :meth:`grab` one new exposure.

    ``exposure_ms`` and ``pixel_format`` are written to the camera at open (None: leave the camera's setting).
    ``interface_address``: the local address the stream comes back to (default: the routed one). ``timeout_s``:
    the longest wait for a frame after its trigger. ``n_buffers``: the Aravis buffer pool.
    """

    can_trigger = True
    stop_wait_s = 0.5  # a grab of a camera that has gone away blocks for seconds of GVCP retries; close() is safe

    def __init__(self, address: str, *, camera_id: str | None = None, exposure_ms: float | None = 5.0,
                 pixel_format: str | None = "Mono8", interface_address: str | None = None,
                 timeout_s: float = 1.0, n_buffers: int = 4) -> None:
        self.address = _check_ipv4(address, "GigE camera address")
        self.camera_id = camera_id or f"gige:{address}"
        if pixel_format is not None and pixel_format not in PIXEL_FORMATS:
            raise VisionError(f"pixel format {pixel_format!r} is not supported; use one of {', '.join(PIXEL_FORMATS)}")
        if exposure_ms is not None and not 0 < exposure_ms < float("inf"):
            raise VisionError(f"exposure must be a finite number of ms > 0, got {exposure_ms!r}")
        if timeout_s <= 0:
            raise VisionError("timeout_s must be > 0")
        self.timeout_s = timeout_s
        self._closed = False
        self._acquiring = False
        self._seq = 0
        self._lock = threading.Lock()
        Aravis = self._arv = load_aravis()
        from gi.repository import Gio, GLib

        self._glib_error = GLib.Error
        local = _check_ipv4(interface_address, "interface address") if interface_address else \
            local_address_for(self.address)
        try:
            device = Aravis.GvDevice.new(Gio.InetAddress.new_from_string(local),
                                         Gio.InetAddress.new_from_string(self.address))
            self._device = device
            self._cam = cam = Aravis.Camera.new_with_device(device)
            device.connect("control-lost", self._on_control_lost)
            self._control_lost = False
            cam.set_acquisition_mode(Aravis.AcquisitionMode.CONTINUOUS)
            if cam.is_feature_available("TriggerSelector"):
                cam.set_string("TriggerSelector", "FrameStart")
            cam.set_string("TriggerMode", "On")
            cam.set_string("TriggerSource", "Software")
            if exposure_ms is not None:
                cam.set_exposure_time(exposure_ms * 1e3)  # µs
            if pixel_format is not None:
                cam.set_pixel_format_from_string(pixel_format)
            self.exposure_s = cam.get_exposure_time() / 1e6
            self.pixel_format = cam.get_pixel_format_as_string()
            if self.pixel_format not in PIXEL_FORMATS:
                raise VisionError(f"{self.camera_id}: camera delivers {self.pixel_format}, which this source "
                                  f"cannot convert; set pixel_format to one of {', '.join(PIXEL_FORMATS)}")
            region = cam.get_region()
            self.width_px, self.height_px = int(region.width), int(region.height)
            self.model = f"{cam.get_vendor_name()} {cam.get_model_name()}"
            self._stream = cam.create_stream(None, None)
            payload = cam.get_payload()
            for _ in range(max(2, n_buffers)):
                self._stream.push_buffer(Aravis.Buffer.new_allocate(payload))
            cam.start_acquisition()
            self._acquiring = True
        except GLib.Error as exc:
            self.close()
            raise VisionError(f"GigE camera {self.address}: {exc.message}") from None
        except VisionError:
            self.close()
            raise

    def _on_control_lost(self, *_: Any) -> None:
        # Aravis's heartbeat thread: the camera stopped answering. Said once, at the time, in one line.
        if not self._control_lost and not self._closed:
            log.warning("GigE camera %s lost: no answer to the control heartbeat", self.address)
        self._control_lost = True

    @staticmethod
    def _drain(stream: Any) -> None:
        """Give back buffers that came in since the last grab (a late frame of an earlier, timed-out trigger)."""
        while (buf := stream.try_pop_buffer()) is not None:
            stream.push_buffer(buf)

    def grab(self) -> Frame | None:
        with self._lock:
            if self._closed:
                return None
            if self._control_lost:
                raise VisionError(f"GigE camera {self.address} lost (no answer to the control heartbeat)")
            Arv = self._arv
            # Our own references: close() (from another thread, when a stop does not wait for this grab) hands the
            # camera's over to its release thread.
            cam, stream = self._cam, self._stream
            seq = self._seq
            self._seq += 1  # counted per trigger, so a lost frame leaves a gap in the sequence
            try:
                self._drain(stream)
                t_trigger = time.time()
                cam.software_trigger()
                t_ack = time.time()
                buf = stream.timeout_pop_buffer(int(self.timeout_s * 1e6))
            except self._glib_error as exc:
                raise VisionError(f"GigE camera {self.address}: {exc.message}") from None
            t_done = time.time()
            if buf is None:
                lost = " (camera lost)" if self._control_lost else ""
                raise VisionError(f"GigE camera {self.address}: no frame within {self.timeout_s * 1e3:g} ms of its "
                                  f"software trigger{lost}")
            try:
                status = buf.get_status()
                if status != Arv.BufferStatus.SUCCESS:
                    raise VisionError(f"GigE camera {self.address}: frame lost ({status.value_nick})")
                if buf.get_payload_type() not in (Arv.BufferPayloadType.IMAGE,
                                                  getattr(Arv.BufferPayloadType, "EXTENDED_CHUNK_DATA", None)):
                    raise VisionError(f"GigE camera {self.address}: buffer holds no image")
                h, w = buf.get_image_height(), buf.get_image_width()
                data = buf.get_image_data()
                t_memory = buf.get_system_timestamp() / 1e9 or t_done
            finally:
                stream.push_buffer(buf)  # back into the pool
        image = self._to_mono8(data, h, w)
        readout_s = max(0.0, t_memory - t_ack - self.exposure_s)
        return Frame(image, t_ack, self.camera_id, seq, exposure_s=self.exposure_s, readout_s=readout_s,
                     t_trigger=t_trigger)

    def _to_mono8(self, data: bytes, h: int, w: int) -> np.ndarray:
        fmt = self.pixel_format
        if fmt == "Mono16":
            arr = np.frombuffer(data, dtype="<u2", count=h * w).reshape(h, w)
            return to_mono8(arr)
        arr = np.frombuffer(data, dtype=np.uint8, count=h * w).reshape(h, w)
        if fmt in _BAYER_TO_GRAY:
            import cv2

            return cv2.cvtColor(arr, getattr(cv2, _BAYER_TO_GRAY[fmt]))
        return arr  # Mono8: a read-only view of the one copy, no further copy

    def close(self) -> None:
        """Stop acquisition and release the camera; returns within :data:`CLOSE_WAIT_S`.

        A camera that has gone away answers no GVCP command, and Aravis retries each one (stop acquisition, close
        the stream channel, release control: about 12 s in all), so the release runs on a daemon thread of its
        own: when it is not done in time a warning says the camera was lost, and the process need not wait for it.
        """
        if self._closed:
            return
        self._closed = True
        # The last references go to the thread: Aravis's finalizers (stream channel, control release) write to the
        # camera too, so they must run there, not here.
        held = [getattr(self, "_cam", None), getattr(self, "_stream", None), getattr(self, "_device", None)]
        acquiring, self._acquiring = self._acquiring, False
        self._stream = None
        self._cam = None
        self._device = None
        done = threading.Event()
        threading.Thread(target=_release, args=(held, acquiring, done), daemon=True,
                         name=f"{self.camera_id} close").start()
        del held
        if not done.wait(CLOSE_WAIT_S):
            lost = "it stopped answering its control heartbeat" if self._control_lost else "it does not answer"
            log.warning("GigE camera %s lost (%s): closed without waiting for it", self.address, lost)


CLOSE_WAIT_S = 0.5
"""How long :meth:`GigECamera.close` waits for a camera to confirm its release (a present one takes milliseconds)."""


def _release(held: list[Any], stop_acquisition: bool, done: threading.Event) -> None:
    """Stop acquisition, then drop the stream, camera and device (in that order): their finalizers run here."""
    try:
        cam = held[0]
        if cam is not None and stop_acquisition:
            try:
                cam.stop_acquisition()
            except Exception:  # noqa: BLE001 - the camera may be gone: closing must not raise
                pass
        del cam
        held[1] = None  # the stream first: its channel is the camera's
        held.clear()
    finally:
        done.set()
