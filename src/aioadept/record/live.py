"""The live recording of a run: ``run.rrd`` in the run folder, and the stream to a viewer when one is open.

:class:`RunRecording` is one more observer of the :class:`~aioadept.client.RobotClient` and the
:class:`~aioadept.bus.Communicator` (``on_send``/``on_ack``/``on_request``/``on_response``) and takes the
application's marks, like :class:`aioadept.runs.capture.Recorder`. Its hooks run inside the protocol path, so they only
put the record object on a queue (``SimpleQueue.put``, well under a microsecond); one worker thread does the rest:
converting, forward kinematics, reading and downsampling the frame files, and Rerun's logging calls. A frame is
therefore never read or encoded on the event loop; without a viewer (a file only) the frames are read and logged
by :meth:`RunRecording.close`, after the run, so their ~10 ms of CPU each does not compete with the focus loop.

Where the data comes from besides the hooks: the sim's robot-state stream (``state_endpoint``; a SUB socket on the
loop that keeps at most :data:`STATE_RATE_HZ` samples a second) gives the joints; without it the arm is drawn from
the acked poses by inverse kinematics. The frames are the files the vision node saves with ``--save-frames``
(``frames_dir``), named by the ``camera``/``frame_seq`` of each response.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import queue
import sys
import threading
import time
import uuid
from pathlib import Path
from typing import Any

from aioadept.record.rrd import APP_ID, CellLogger, default_blueprint, frame_file
from aioadept.record.sinks import close_bounded, rrd_incomplete

__all__ = ["STATE_RATE_HZ", "SWITCH_INTERVAL_S", "RunRecording"]

log = logging.getLogger(__name__)

STATE_RATE_HZ = 25.0
"""Robot-state samples drawn per second: smooth motion in the viewer for a fraction of the sim's 100 Hz."""

_STOP = object()

FRAME_WAIT_S = 5.0
"""How long :meth:`RunRecording.close` waits for a served frame's file to appear in ``frames_dir`` before counting it
in ``frames_missing``. The node writes a frame after answering, on a low-priority thread (a 1024x768 PNG takes
~10 ms of CPU), so on a loaded machine a file may land well after its response; a node that saves nothing costs one
such wait (the rest are not waited for)."""

SWITCH_INTERVAL_S = 0.0005
"""The interpreter's GIL switch interval while a recording runs (Python's default is 5 ms). The worker thread holds
the GIL in bursts (conversion, kinematics, Rerun's logging calls); with 5 ms, a response arriving during a burst
waits up to 5 ms before the event loop may even read it, more when the worker is niced and preempted. Measured
with ``aioadept demo --fast``: the response's way back (sent by the node -> received by the MCN)
reached 7-15 ms per run with the default, 0.8-3 ms with 0.5 ms."""

_switch_lock = threading.Lock()
_switch_users = 0
_switch_saved: float | None = None


def _shorten_switch_interval() -> None:
    global _switch_users, _switch_saved
    with _switch_lock:
        if _switch_users == 0:
            _switch_saved = sys.getswitchinterval()
            if _switch_saved > SWITCH_INTERVAL_S:
                sys.setswitchinterval(SWITCH_INTERVAL_S)
        _switch_users += 1


def _restore_switch_interval() -> None:
    global _switch_users, _switch_saved
    with _switch_lock:
        _switch_users -= 1
        if _switch_users == 0 and _switch_saved is not None:
            sys.setswitchinterval(_switch_saved)
            _switch_saved = None


def _loop_clock() -> float:
    try:
        return asyncio.get_running_loop().time()
    except RuntimeError:
        return time.monotonic()


class RunRecording:
    """Record a run into ``rrd_path`` (and stream it to ``viewer_url``, a ``rerun+http://HOST:PORT/proxy``).

    Use as an (async) context manager, or call :meth:`start`/:meth:`close`. ``clock_ref``: an object with
    ``start_wall_epoch_s``/``start_loop_s`` (the run's :class:`aioadept.runs.capture.Recorder`) so both logs share the
    same mapping from loop time to wall time. ``name`` becomes the recording's name in the viewer.
    ``short_switch_interval``: while it runs, set the interpreter's GIL switch interval to
    :data:`SWITCH_INTERVAL_S` (restored when the last such recording closes). The CLIs turn it on; it is off by
    default because it is process-wide, a choice for the application, not for a library object. ``arm``: the
    robot model the run uses (:class:`~aioadept.record.rrd.CellLogger`; default the Viper s850).
    """

    def __init__(self, rrd_path: str | os.PathLike[str] | None, *, viewer_url: str | None = None,
                 state_endpoint: str | None = None, frames_dir: str | os.PathLike[str] | None = None,
                 clock_ref: Any = None, name: str | None = None, short_switch_interval: bool = False,
                 world: Any = None, arm: Any = None) -> None:
        if rrd_path is None and viewer_url is None:
            raise ValueError("RunRecording: give a file (rrd_path), a viewer (viewer_url), or both")
        import rerun as rr

        self.rr = rr
        self.rrd_path = None if rrd_path is None else Path(rrd_path)
        self.viewer_url = viewer_url
        self.state_endpoint = state_endpoint
        self.frames_dir = None if frames_dir is None else Path(frames_dir)
        if clock_ref is not None:
            wall, loop_t = float(clock_ref.start_wall_epoch_s), float(clock_ref.start_loop_s)
        else:
            wall, loop_t = time.time(), _loop_clock()
        self.loop_to_epoch_s = wall - loop_t
        self.rec = rr.RecordingStream(APP_ID, recording_id=str(uuid.uuid4()))
        sinks: list[Any] = []
        # The file is written under a temporary name and renamed to ``rrd_path`` by close() once complete: a full
        # disk then leaves no truncated run.rrd under its final name.
        self._rrd_tmp = None if self.rrd_path is None else self.rrd_path.with_name(
            f".{self.rrd_path.name}.{os.getpid()}.tmp")
        if self.rrd_path is not None:
            self.rrd_path.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(str(self._rrd_tmp)))
        if viewer_url is not None:
            sinks.append(rr.GrpcSink(viewer_url))
        self.rec.set_sinks(*sinks)
        # Sent as a message, not as set_sinks(default_blueprint=...): that writes the blueprint synchronously and
        # blocked for ever when the file could not be written (a full disk hung `aioadept focus` before its first
        # move; tests/integration/test_results_kept.py).
        self.rec.send_blueprint(default_blueprint())
        if name:
            self.rec.send_recording_name(name)
        self.logger = CellLogger(self.rec, loop_to_epoch_s=self.loop_to_epoch_s, arm=arm)
        self.world_logger = None
        """The simulated world's parts (aioadept.record.world), when ``world`` (a WorldConfig) is given: they are
        drawn from the sim's ``world.state`` stream on ``state_endpoint``."""
        if world is not None:
            from aioadept.record.world import WorldLogger

            self.world_logger = WorldLogger(self.rec, world)
        self._q: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._thread: threading.Thread | None = None
        self._state_task: asyncio.Task[None] | None = None
        self._errors = 0
        self.frames_missing = 0
        self._deferred_frames: list[tuple[dict[str, Any], int]] = []  # file only: logged by close()
        self._frame_wait_s = FRAME_WAIT_S  # 0 after a frame never came: a node not saving costs one wait only
        self.short_switch_interval = short_switch_interval
        self.closed = False
        self.error: str | None = None
        """Why the recording could not be written completely (set by :meth:`close`), else None."""

    # -- hooks (hot path: one queue put each)
    def on_send(self, msg: Any) -> None:
        self._q.put(("send", msg))

    def on_ack(self, result: Any) -> None:
        self._q.put(("ack", result))

    def on_request(self, request: Any) -> None:
        self._q.put(("request", request))

    def on_response(self, response: Any) -> None:
        self._q.put(("response", response))

    def mark(self, name: str, value: Any = None, *, t_s: float | None = None) -> None:
        self._q.put(("mark", (_loop_clock() if t_s is None else t_s, name, value)))

    def focus_result(self, result: Any) -> None:
        """The run's :class:`~aioadept.apps.focus.FocusResult`: draws the focus plane at its inspection pose."""
        self._q.put(("result", result))

    # -- life cycle
    def start(self) -> RunRecording:
        if self._thread is None:
            if self.short_switch_interval:
                _shorten_switch_interval()  # restored by close(): see SWITCH_INTERVAL_S
            self._thread = threading.Thread(target=self._work, name="rerun-recording", daemon=True)
            self._thread.start()
            if self.state_endpoint:
                try:
                    loop = asyncio.get_running_loop()
                except RuntimeError:
                    loop = None
                if loop is not None:
                    self._state_task = loop.create_task(self._follow_state(self.state_endpoint),
                                                        name="rerun-state")
        return self

    async def aclose(self) -> None:
        """Stop following the state stream, then :meth:`close` (in a thread: the final flush may take a moment)."""
        if self._state_task is not None:
            self._state_task.cancel()
            await asyncio.gather(self._state_task, return_exceptions=True)
            self._state_task = None
        await asyncio.to_thread(self.close)

    def close(self, timeout_s: float = 10.0) -> None:
        """Log what is queued, then flush and close the file (and the viewer stream). Idempotent."""
        if self.closed:
            return
        self.closed = True
        if self._thread is not None:
            self._q.put((_STOP, None))
            self._thread.join(timeout_s)
            if self.short_switch_interval:
                _restore_switch_interval()
            if self._thread.is_alive():  # still busy: its list of deferred frames is not ours to take
                self.frames_missing += len(self._deferred_frames)
                log.warning("run.rrd: the recording worker did not finish within %.0f s; frames not logged",
                            timeout_s)
            else:
                # The run is over: the frames are logged here, in the closing thread at normal priority, not by
                # the worker, which runs at nice 19 so as never to compete with a running focus loop (on a loaded
                # machine that share of a core made a dozen frames outlast the join and get lost).
                self._log_deferred_frames()
        else:
            self._drain()
        # A recording never fails a run, nor holds it up: a full disk (or any sink error) is said once and the run's
        # result stands.
        errors = close_bounded(self.rec, timeout_s)
        if self._rrd_tmp is not None and not errors:
            # Rerun's file sink reports a failed write (ENOSPC) only in its own log, not to Python: the file is
            # checked instead, for the footer a complete recording ends with.
            why = rrd_incomplete(self._rrd_tmp)
            if why:
                errors.append(why)
        if self._rrd_tmp is not None:
            try:
                if errors:
                    os.unlink(self._rrd_tmp)  # not there rather than cut short
                else:
                    os.replace(self._rrd_tmp, self.rrd_path)
            except OSError as exc:
                errors.append(exc.strerror or str(exc))
                with contextlib.suppress(OSError):
                    os.unlink(self._rrd_tmp)
        if errors:
            self.error = "; ".join(errors)
            log.warning("run.rrd not written (%s): %s", self.rrd_path, self.error)

    def __enter__(self) -> RunRecording:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    async def __aenter__(self) -> RunRecording:
        return self.start()

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    # -- worker thread
    def _work(self) -> None:
        # The recording yields the CPU to the control loop: on a small machine they share the same cores.
        with contextlib.suppress(OSError, AttributeError):
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 19)
        while True:
            kind, obj = self._q.get()
            if kind is _STOP:
                return  # deferred frames: close() logs them
            self._handle(kind, obj)

    def _drain(self) -> None:
        while True:
            try:
                kind, obj = self._q.get_nowait()
            except queue.Empty:
                self._log_deferred_frames()
                return
            if kind is not _STOP:
                self._handle(kind, obj)

    def _log_deferred_frames(self) -> None:
        frames, self._deferred_frames = self._deferred_frames, []
        for attrs, step in frames:
            try:
                self._frame(attrs, step)
            except Exception:  # as _handle: never take the run down
                self._errors += 1
                if self._errors == 1:
                    log.exception("recording: could not log a frame (further errors are counted only)")

    def _handle(self, kind: str, obj: Any) -> None:
        lg = self.logger
        try:
            if kind == "send":
                lg.command(obj.id, obj.skill, obj.args, obj.t_send_s)
            elif kind == "ack":
                ack = obj.ack
                status = getattr(ack, "status", None)
                status_text = None if status is None else str(getattr(status, "value", status))
                err = getattr(ack, "error_message", None) if status_text not in (None, "done") else None
                lg.ack(obj.id, obj.skill, status_text, getattr(ack, "pose", None), obj.t_recv_s,
                       t_send_loop_s=obj.t_send_s, error=err)
            elif kind == "request":
                lg.request(obj.id, obj.event_type, obj.attributes or {}, obj.t_send_s)
            elif kind == "response":
                attrs = dict(obj.attributes or {})
                step = lg._step  # the sharpness of this response gets this step index
                lg.response(obj.id, obj.event_type, attrs, obj.t_recv_s, t_send_loop_s=obj.t_send_s)
                if self.viewer_url is None:
                    # Only a file: the frame (PNG decode, downsampling, encoding: ~10 ms of CPU) can wait for
                    # close(), so it does not compete with the focus loop for the cores.
                    self._deferred_frames.append((attrs, step))
                else:
                    self._frame(attrs, step)
            elif kind == "mark":
                t, name, value = obj
                lg.mark(name, value, t)
            elif kind == "state":
                lg.state(obj.wall_time_s, obj.joints_deg, obj.pose)
            elif kind == "world" and self.world_logger is not None:
                self.world_logger.state(obj)
            elif kind == "result":
                lg.focus_plane(obj.inspection_pose, offset_mm=float(obj.peak_offset_mm))
        except Exception:  # a recording must never take the run down; say it once, then count
            self._errors += 1
            if self._errors == 1:
                log.exception("recording: could not log a %s event (further errors are counted only)", kind)

    def _frame(self, attrs: dict[str, Any], step: int) -> None:
        if self.frames_dir is None or attrs.get("error") or "frame_seq" not in attrs:
            return
        path = frame_file(self.frames_dir, str(attrs.get("camera", "")), int(attrs["frame_seq"]))
        import cv2

        # The node saves a frame after it has answered (vision.node: off the response path), so the file usually
        # appears a few ms after the response; it is renamed into place whole (FrameRecorder), so once it exists
        # it is complete. Wait for it here, in the worker thread, never on the loop.
        deadline = time.monotonic() + self._frame_wait_s
        while not path.is_file() and time.monotonic() < deadline:
            time.sleep(0.005)
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED) if path.is_file() else None
        if img is None:
            self._frame_wait_s = 0.0
            self.frames_missing += 1
            return
        self.logger.frame(img, float(attrs.get("frame_t", time.time())), step=step,
                          camera=str(attrs.get("camera", "")))

    # -- robot state stream (on the loop: a SUB socket, decimated before it reaches the queue)
    async def _follow_state(self, endpoint: str) -> None:
        from aioadept.bus.messages import ROBOT_STATE_TOPIC, WORLD_STATE_TOPIC, RobotState, WorldState
        from aioadept.bus.pubsub import Subscriber

        min_dt = 1.0 / STATE_RATE_HZ
        last_t = last_world_t = -1e9
        last_motion: bool | None = None
        topics = [ROBOT_STATE_TOPIC] + ([WORLD_STATE_TOPIC] if self.world_logger is not None else [])
        try:
            # (a world sample carries its events once: the queue must not drop them, hence the larger HWM)
            sub = Subscriber(endpoint, topics=topics, rcvhwm=16 if len(topics) == 1 else 256)
        except Exception as exc:  # noqa: BLE001 - no state stream: the arm is drawn from the acks
            log.warning("recording: cannot follow the robot state at %s (%s); drawing the arm from the acks",
                        endpoint, exc)
            return
        try:
            while True:
                topic, payload = await sub.recv()
                if topic == WORLD_STATE_TOPIC:
                    try:
                        ws = WorldState.from_bytes(payload)
                    except Exception:  # noqa: BLE001 - a stranger's message on the topic: skip it
                        continue
                    # Every sample with events (each is sent once), and at most STATE_RATE_HZ otherwise.
                    if ws.events or ws.wall_time_s - last_world_t >= min_dt:
                        last_world_t = ws.wall_time_s
                        self._q.put(("world", ws))
                    continue
                try:
                    st = RobotState.from_bytes(payload)
                except Exception:  # noqa: BLE001 - a stranger's message on the topic: skip it
                    continue
                # Keep the first sample of every start and stop of a motion, and at most STATE_RATE_HZ otherwise.
                if st.wall_time_s - last_t >= min_dt or st.in_motion != last_motion:
                    last_t, last_motion = st.wall_time_s, st.in_motion
                    self._q.put(("state", st))
        finally:
            with contextlib.suppress(Exception):
                sub.close()
