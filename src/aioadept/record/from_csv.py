"""``run.rrd`` for an older run folder, rebuilt from its CSV logs (what ``aioadept analyze RUN`` writes).

The CSV logs hold every command with its ack, every vision request with its response, and the marks, with the
same loop-clock stamps the live hooks saw; ``run.json`` gives the loop-to-wall offset and the focus result. They
are replayed in time order through the same :class:`~aioadept.record.rrd.CellLogger` as a live run, so both
recordings have the same entities. What the CSV does not have is not invented: the arm is drawn from the acked
poses (no state stream was kept), and frames appear only when the folder has the vision node's saved frames
(``frames/``, ``--save-frames``).
"""

from __future__ import annotations

import contextlib
import os
import uuid
from pathlib import Path
from typing import Any

from aioadept.runs.capture import load_run
from aioadept.geometry import Pose
from aioadept.record.model import run_model
from aioadept.record.rrd import APP_ID, CellLogger, default_blueprint, frame_file
from aioadept.record.sinks import close_bounded, rrd_incomplete

__all__ = ["rrd_from_run"]


def rrd_from_run(run_dir: str | os.PathLike[str], out: str | os.PathLike[str] | None = None) -> Path:
    """Write ``run.rrd`` (or ``out``) for the run folder ``run_dir``; returns its path.

    Raises ``FileNotFoundError``/``ValueError`` as :func:`aioadept.runs.capture.load_run` for a folder that is not
    a run.
    """
    import rerun as rr

    run = load_run(run_dir)
    path = Path(out) if out is not None else Path(run_dir) / "run.rrd"
    meta = run.metadata
    offset = float(meta.get("start_wall_epoch_s", 0.0)) - float(meta.get("start_loop_s", 0.0))
    events = _events(run)

    rec = rr.RecordingStream(APP_ID, recording_id=str(uuid.uuid4()))
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    rec.set_sinks(rr.FileSink(str(tmp)))
    rec.send_blueprint(default_blueprint())  # not set_sinks(default_blueprint=...): see record.live
    try:
        rec.send_recording_name(Path(run_dir).resolve().name)
        lg = CellLogger(rec, loop_to_epoch_s=offset, arm=run_model(meta))
        frames_dir = Path(run_dir) / "frames"
        result = (meta.get("parameters") or {}).get("result") or None
        plane_done = _replay(lg, events, frames_dir, result)
        if not plane_done and isinstance(result, dict) and result.get("inspection_pose") and events:
            lg._at(events[-1][0] + offset)
            lg.focus_plane(Pose(**result["inspection_pose"]), offset_mm=_float(result.get("peak_offset_mm")))
    finally:
        errors = close_bounded(rec, 10.0)
    if not errors and (why := rrd_incomplete(tmp)):  # a full disk: Rerun's sink says so only in its own log
        errors.append(why)
    if errors:  # never publish a cut-short recording under the real name
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise OSError(f"{path}: not written: {'; '.join(errors)}")
    os.replace(tmp, path)
    return path


def _events(run: Any) -> list[tuple[float, int, str, Any]]:
    """The run's sends, acks, requests, responses and marks in time order (at one instant: sends first)."""
    events: list[tuple[float, int, str, Any]] = []
    for r in run.robot:
        if r.t_send_s is not None:
            events.append((r.t_send_s, 0, "send", r))
        if r.t_recv_s is not None:
            events.append((r.t_recv_s, 1, "ack", r))
    for v in run.vision:
        if v.t_send_s is not None:
            events.append((v.t_send_s, 0, "request", v))
        if v.t_recv_s is not None:
            events.append((v.t_recv_s, 1, "response", v))
    for m in run.marks:
        events.append((m.t_s, 2, "mark", m))
    events.sort(key=lambda e: (e[0], e[1]))
    return events


def _replay(lg: CellLogger, events: list[tuple[float, int, str, Any]], frames_dir: Path, result: Any) -> bool:
    """Log the events; returns whether the focus plane was drawn (at the retract mark)."""
    plane_done = False
    for _t, _o, kind, obj in events:
        if kind == "send":
            lg.command(obj.id, obj.skill, obj.args, obj.t_send_s)
        elif kind == "ack":
            err = obj.error_message if obj.status not in (None, "done") else None
            lg.ack(obj.id, obj.skill, obj.status, obj.pose, obj.t_recv_s, t_send_loop_s=obj.t_send_s,
                   error=err)
        elif kind == "request":
            lg.request(obj.id, obj.event_type, obj.request_attributes, obj.t_send_s)
        elif kind == "response":
            attrs: dict[str, Any] = dict(obj.response_extra)
            # frame_seq has its own vision.csv column since the trigger spans (older folders: response_extra)
            for key, val in (("sharpness", obj.sharpness), ("frame_t", obj.frame_t_epoch_s),
                             ("proc_time_ms", obj.proc_time_ms), ("error", obj.error),
                             ("frame_seq", getattr(obj, "frame_seq", None))):
                if val is not None:
                    attrs[key] = val
            step = lg._step
            lg.response(obj.id, obj.response_type, attrs, obj.t_recv_s, t_send_loop_s=obj.t_send_s)
            _replay_frame(lg, frames_dir, attrs, step)
        elif kind == "mark":
            if obj.name == "retract" and isinstance(result, dict) and result.get("inspection_pose"):
                lg.mark(obj.name, obj.value, obj.t_s, plane=False)  # the plane: from the saved result
                lg.focus_plane(Pose(**result["inspection_pose"]),
                               offset_mm=_float(result.get("peak_offset_mm")))
                plane_done = True
            elif obj.name == "retract":
                lg.mark(obj.name, obj.value, obj.t_s)
                plane_done = lg.counts.get("focus_plane", 0) > 0
            else:
                lg.mark(obj.name, obj.value, obj.t_s)
    return plane_done


def _float(v: Any) -> float | None:
    try:
        return None if v is None else float(v)
    except (TypeError, ValueError):
        return None


def _replay_frame(lg: CellLogger, frames_dir: Path, attrs: dict[str, Any], step: int) -> None:
    if not frames_dir.is_dir() or attrs.get("error") or "frame_seq" not in attrs:
        return
    path = frame_file(frames_dir, str(attrs.get("camera", "")), int(attrs["frame_seq"]))
    if not path.is_file():
        return
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is not None and "frame_t" in attrs:
        lg.frame(img, float(attrs["frame_t"]), step=step)
