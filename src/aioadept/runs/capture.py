"""Timing capture: a recorder fed by the RobotClient and Communicator observer hooks, and the run folder format.

The recorder and the run folder format it writes are one contract: the columns written and the columns read back
(older folders too).

Where it sits in the data path: ``RobotClient`` calls ``on_send``/``on_ack`` and ``bus.Communicator`` calls
``on_request``/``on_response`` (see ``docs/interfaces.md``); the application adds free-form marks
(``recorder.mark("iteration", i)``). After the run, :meth:`Recorder.save` writes a run folder that
:func:`load_run` reads back and :mod:`aioadept.analysis` turns into the paper's metrics::

    recorder = Recorder()
    async with RobotClient(host, port, observers=[recorder]) as rc:
        comm.add_observer(recorder)
        ...
    recorder.save("runs/0001", metadata={"appr_speed": 25, "delta_z_mm": 2.0})
    run = load_run("runs/0001")

The hooks run inside the protocol path, so they only append the record object to a list: pairing sends with acks,
flattening poses and formatting numbers happen in :meth:`Recorder.snapshot`/:meth:`Recorder.save`, after the run.
The folder layout and every column (with units) are documented in ``docs/timing-log.md``.

Every file of a run folder is written through :func:`write_atomic` (a temporary file in the same folder, flushed to
disk, then ``os.replace``): a full disk or a permission error never leaves a truncated file, and a file written
before keeps its old content. :meth:`Recorder.save` writes what it can and raises :class:`RunSaveError` naming
what it could not.
"""

from __future__ import annotations

import asyncio
import csv
import json
import math
import os
import platform
import socket
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import suppress
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import IO, Any

from aioadept.geometry import Pose
from aioadept.errors import RunSaveError

__all__ = [
    "FORMAT_VERSION", "MARK_COLUMNS", "ROBOT_COLUMNS", "VISION_COLUMNS", "Mark", "Recorder", "RobotRecord", "Run",
    "VisionRecord", "load_run", "note_not_written", "write_atomic",
]

FORMAT_VERSION = 1
"""Version of the run folder layout; bumped when a column changes meaning or is removed."""

ROBOT_COLUMNS: tuple[str, ...] = (
    "seq", "id", "skill", "args", "batch", "t_send_s", "t_recv_s", "t_start_s", "t_done_s", "status",
    "pose_x_mm", "pose_y_mm", "pose_z_mm", "pose_yaw_deg", "pose_pitch_deg", "pose_roll_deg",
    "error_code", "error_message",
)
VISION_COLUMNS: tuple[str, ...] = (
    "seq", "id", "event_type", "attempts", "t_send_s", "t_recv_s", "response_type", "sharpness", "frame_t_epoch_s",
    "proc_time_ms", "error", "request_attributes", "response_extra",
    "t_trigger_epoch_s", "t_exposure_start_epoch_s", "exposure_ms", "readout_ms", "frame_seq",
)
# Columns added after FORMAT_VERSION 1 was first written: a run folder without them still loads (None).
_VISION_OPTIONAL = ("t_trigger_epoch_s", "t_exposure_start_epoch_s", "exposure_ms", "readout_ms", "frame_seq")
MARK_COLUMNS: tuple[str, ...] = ("seq", "t_s", "name", "value")

# Response attributes that get their own column; any other attribute goes to the JSON column ``response_extra``.
_VISION_KNOWN = {"sharpness": "sharpness", "frame_t": "frame_t_epoch_s", "proc_time_ms": "proc_time_ms",
                 "error": "error", "t_trigger": "t_trigger_epoch_s", "t_exposure_start": "t_exposure_start_epoch_s",
                 "exposure_ms": "exposure_ms", "readout_ms": "readout_ms", "frame_seq": "frame_seq"}

CLOCK_NOTES = {
    "t_send_s/t_recv_s": "client side, asyncio loop clock (loop.time(), monotonic seconds) at write/read",
    "t_start_s/t_done_s": "robot server clock: seconds since server start, 1 ms resolution (V+ TIMER(-3))",
    "frame_t_epoch_s": "vision node, time.time() epoch seconds when the frame was taken",
    "t_trigger_epoch_s/t_exposure_start_epoch_s": "vision node, time.time() epoch seconds of the software trigger "
                                                  "(empty: free-running) and of the exposure start",
    "marks.t_s": "same loop clock as t_send_s",
    "start_wall_epoch_s/start_loop_s": "read together when the recorder was created: epoch = loop + difference",
}


# --------------------------------------------------------------------------------------------------- values


@dataclass(frozen=True, slots=True)
class RobotRecord:
    """One robot command message and, if it came, its ack. Receive/server fields are None when never acked."""

    seq: int
    id: str
    skill: str
    args: tuple[float, ...]
    batch: int | None
    t_send_s: float | None
    t_recv_s: float | None = None
    t_start_s: float | None = None
    t_done_s: float | None = None
    status: str | None = None
    pose: Pose | None = None
    error_code: int | None = None
    error_message: str | None = None

    @property
    def acked(self) -> bool:
        return self.t_recv_s is not None


@dataclass(frozen=True, slots=True)
class VisionRecord:
    """One vision request and, if it came, its response. Response fields are None when never answered."""

    seq: int
    id: str
    event_type: str
    t_send_s: float | None
    t_recv_s: float | None = None
    response_type: str | None = None
    sharpness: float | None = None
    frame_t_epoch_s: float | None = None
    proc_time_ms: float | None = None
    error: str | None = None
    attempts: int = 1
    request_attributes: Mapping[str, Any] = field(default_factory=dict)
    response_extra: Mapping[str, Any] = field(default_factory=dict)
    t_trigger_epoch_s: float | None = None
    """Epoch s of the software trigger that took the frame (None: free-running, or an older node)."""
    t_exposure_start_epoch_s: float | None = None
    exposure_ms: float | None = None
    readout_ms: float | None = None
    """From the exposure's end until the frame was in the node's memory (sensor readout + transfer)."""
    frame_seq: int | None = None

    @property
    def answered(self) -> bool:
        return self.t_recv_s is not None


@dataclass(frozen=True, slots=True)
class Mark:
    """A free-form label the application put on the timeline (``t_s`` on the loop clock)."""

    seq: int
    t_s: float
    name: str
    value: Any = None


@dataclass(frozen=True, slots=True)
class Run:
    """One recorded run: its records in send order and its ``run.json`` metadata (``path`` None if in memory)."""

    robot: tuple[RobotRecord, ...]
    vision: tuple[VisionRecord, ...]
    marks: tuple[Mark, ...] = ()
    metadata: Mapping[str, Any] = field(default_factory=dict)
    path: Path | None = None

    @property
    def parameters(self) -> dict[str, Any]:
        """The ``metadata=`` dict given to :meth:`Recorder.save` (e.g. appr_speed, delta_z_mm)."""
        return dict(self.metadata.get("parameters") or {})

    @property
    def name(self) -> str:
        # An analysis of several runs names each by its distinguishing path (metadata "name"); else the folder.
        if self.metadata.get("name"):
            return str(self.metadata["name"])
        return self.path.name if self.path is not None else "run"


# --------------------------------------------------------------------------------------------------- recorder


def _loop_clock() -> float:
    # The records' own timestamps are loop.time(); marks use the same clock when a loop runs.
    try:
        return asyncio.get_running_loop().time()
    except RuntimeError:
        return time.monotonic()


class Recorder:
    """Observer of a RobotClient (``on_send``/``on_ack``) and a Communicator (``on_request``/``on_response``).

    Hooks append the record object and return: no pairing, no formatting, no I/O. ``clock`` (keyword) gives the
    time for :meth:`mark`; the default is the running loop's ``time()`` (``time.monotonic()`` outside a loop), the
    clock the client and the communicator stamp their records with.
    """

    def __init__(self, *, clock: Callable[[], float] | None = None) -> None:
        self._clock = clock or _loop_clock
        self._sends: list[Any] = []
        self._acks: list[Any] = []
        self._requests: list[Any] = []
        self._responses: list[Any] = []
        self._marks: list[tuple[float, str, Any]] = []
        # Read back to back so an analysis can map loop times to wall time later.
        self.start_wall_epoch_s = time.time()
        self.start_loop_s = self._clock()

    # -- hooks (hot path)
    def on_send(self, msg: Any) -> None:
        self._sends.append(msg)

    def on_ack(self, result: Any) -> None:
        self._acks.append(result)

    def on_request(self, request: Any) -> None:
        self._requests.append(request)

    def on_response(self, response: Any) -> None:
        self._responses.append(response)

    def mark(self, name: str, value: Any = None, *, t_s: float | None = None) -> None:
        """Label the timeline now (or at ``t_s``, loop-clock seconds), e.g. ``mark("iteration", 3)``.

        ``value`` should be JSON-serialisable (str, number, bool, None, lists/dicts of those) to survive a save.
        """
        self._marks.append((self._clock() if t_s is None else t_s, name, value))

    # -- after the run
    def snapshot(self, *, metadata: Mapping[str, Any] | None = None) -> Run:
        """The records so far as plain values, sends paired with acks by message id (in memory, no file).

        ``metadata`` becomes the run's ``parameters``, as with :meth:`save`.
        """
        return Run(robot=_robot_records(self._sends, self._acks),
                   vision=_vision_records(self._requests, self._responses),
                   marks=tuple(Mark(i, float(t), str(n), v) for i, (t, n, v) in enumerate(self._marks)),
                   metadata={"start_wall_epoch_s": self.start_wall_epoch_s, "start_loop_s": self.start_loop_s,
                             "parameters": dict(metadata or {})})

    def save(self, run_dir: str | os.PathLike[str], *, metadata: Mapping[str, Any] | None = None) -> Path:
        """Write ``robot.csv``, ``vision.csv``, ``marks.csv`` and ``run.json`` into ``run_dir`` (created if needed).

        ``metadata`` (the run's parameters: approach speed, delta_z, ...) is stored under ``parameters`` in
        ``run.json``; it must be JSON-serialisable (other values are stored as their ``repr``). Parquet copies of
        the three tables are written too when ``pyarrow`` imports. Returns the folder path.

        Each file is written atomically (:func:`write_atomic`) and independently of the others; ``run.json``, the
        mark of a complete folder, only when every table was written. Raises :class:`RunSaveError` (an OSError)
        naming the files not written, after writing all the others.
        """
        path = Path(run_dir)
        run = self.snapshot()
        tables = {
            "robot": (ROBOT_COLUMNS, [_robot_row(r) for r in run.robot]),
            "vision": (VISION_COLUMNS, [_vision_row(v) for v in run.vision]),
            "marks": (MARK_COLUMNS, [(m.seq, m.t_s, m.name, _json(m.value)) for m in run.marks]),
        }
        files: list[str] = []
        failed: dict[str, str] = {}
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            names = [f"{n}.csv" for n in tables] + ["run.json"]
            raise RunSaveError(path, (), {n: f"cannot create the folder: {_why(exc)}" for n in names}) from exc
        for name, (columns, rows) in tables.items():
            try:
                _write_csv(path / f"{name}.csv", columns, rows)
                files.append(f"{name}.csv")
            except OSError as exc:
                failed[f"{name}.csv"] = _why(exc)
        pq_files, pq_failed = _write_parquet(path, tables)
        files += pq_files
        failed.update(pq_failed)
        if any(n.endswith(".csv") for n in failed):
            failed["run.json"] = "not written because a table is missing: the folder is incomplete"
            raise RunSaveError(path, files, failed)
        from aioadept import __version__

        now = time.time()
        info = {
            "format": "aioadept-run",
            "format_version": FORMAT_VERSION,
            "aioadept_version": __version__,
            "start_wall_time_utc": _iso(self.start_wall_epoch_s),
            "start_wall_epoch_s": self.start_wall_epoch_s,
            "start_loop_s": self.start_loop_s,
            "saved_wall_time_utc": _iso(now),
            "host": socket.gethostname(),
            "python": sys.version.split()[0],
            "platform": platform.platform(),
            "parameters": dict(metadata or {}),
            "clocks": CLOCK_NOTES,
            "counts": {"robot": len(run.robot), "vision": len(run.vision), "marks": len(run.marks)},
            "files": files,
            "not_written": dict(failed),
        }
        try:  # run.json appears last and whole: its presence means the folder is complete
            write_atomic(path / "run.json", _with_reserve(json.dumps(info, indent=2, default=repr) + "\n"))
            files.append("run.json")
        except OSError as exc:
            failed["run.json"] = _why(exc)
        if failed:
            raise RunSaveError(path, files, failed)
        return path


def note_not_written(run_dir: str | os.PathLike[str], not_written: Mapping[str, str]) -> bool:
    """Add outputs written after ``run.json`` that failed (the vision node's frames, the analysis, ...) to its
    ``not_written`` (file name -> reason), so the folder says itself what it lacks. Returns False, without raising,
    when ``run.json`` is missing or cannot be rewritten (the disk still full): the caller says so itself."""
    path = Path(run_dir) / "run.json"
    try:
        old = path.read_bytes()
        info = json.loads(old)
        if not isinstance(info, dict):
            return False
        info["not_written"] = {**(info.get("not_written") or {}), **dict(not_written)}
        text = json.dumps(info, indent=2, default=repr) + "\n"
        try:
            write_atomic(path, _with_reserve(text))
        except OSError:
            # The disk is full (the usual reason to be here): no room for a temporary file. Overwrite in place,
            # within the bytes run.json already holds (its reserve), which needs no new block on common filesystems;
            # a crash during this one small write could spoil run.json, a risk taken only when the alternative is a
            # folder that does not say what it lacks.
            data = text.encode("utf-8")
            if len(data) > len(old):
                return False
            with open(path, "r+b") as f:
                f.write(data + b" " * (len(old) - len(data)))
                f.flush()
                os.fsync(f.fileno())
    except (OSError, ValueError):
        return False
    return True


RUN_JSON_RESERVE = 2048
"""Trailing blanks after ``run.json``'s JSON: room for :func:`note_not_written` to list outputs that failed later
on a full disk (where it cannot write a temporary file) by overwriting the file in place."""


def _with_reserve(text: str) -> str:
    return text + " " * (RUN_JSON_RESERVE - 1) + "\n"


def _open_for_write(path: Path, binary: bool) -> IO[Any]:
    """The one place run-folder bytes go to disk (tests inject a full disk here)."""
    if binary:
        return open(path, "xb")  # noqa: SIM115 - closed by write_atomic
    return open(path, "x", newline="", encoding="utf-8")  # noqa: SIM115


def write_atomic(path: str | os.PathLike[str], fill: Callable[[IO[Any]], None] | str | bytes, *,
                 binary: bool | None = None) -> Path:
    """Write a file so that it is either complete or not changed: a temporary file next to it, fsync, os.replace.

    ``fill`` is the text/bytes to write or a function writing to the open file (text mode, UTF-8, ``newline=""``,
    unless ``fill`` is bytes or ``binary=True``). On any error the temporary file is removed and the error raised; ``path`` keeps its
    old content.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    if binary is None:
        binary = isinstance(fill, bytes)
    try:
        with _open_for_write(tmp, binary) as f:
            if isinstance(fill, (str, bytes)):
                f.write(fill)
            else:
                fill(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with suppress(OSError):
            os.unlink(tmp)
        raise
    return path


def _why(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return f"{type(exc).__name__}: {exc}"


def _robot_records(sends: Sequence[Any], acks: Sequence[Any]) -> tuple[RobotRecord, ...]:
    by_id: dict[str, Any] = {}
    for res in acks:
        by_id.setdefault(res.id, res)
    rows: list[RobotRecord] = []
    seen: set[str] = set()
    for msg in sends:
        if msg.id in seen:  # a re-sent id: the first send is the one the server acks against
            continue
        seen.add(msg.id)
        rows.append(_robot_record(len(rows), msg, by_id.get(msg.id)))
    # Acks whose send we never saw (observer added late): keep them, the result carries the send fields too.
    for res in acks:
        if res.id not in seen:
            seen.add(res.id)
            rows.append(_robot_record(len(rows), res, res))
    return tuple(rows)


def _robot_record(seq: int, msg: Any, res: Any | None) -> RobotRecord:
    args = tuple(msg.args)
    batch = getattr(msg, "batch", None)
    if res is None:
        return RobotRecord(seq, msg.id, msg.skill, args, batch, _float(msg.t_send_s))
    ack = res.ack
    status = getattr(ack, "status", None)
    pose = getattr(ack, "pose", None)
    return RobotRecord(
        seq, msg.id, msg.skill, args, batch, _float(msg.t_send_s), _float(res.t_recv_s),
        _float(getattr(ack, "t_start_s", None)), _float(getattr(ack, "t_done_s", None)),
        None if status is None else str(getattr(status, "value", status)),
        None if pose is None else Pose.from_seq(tuple(pose)),
        getattr(ack, "error_code", None), getattr(ack, "error_message", None),
    )


def _vision_records(requests: Sequence[Any], responses: Sequence[Any]) -> tuple[VisionRecord, ...]:
    first: dict[str, Any] = {}
    attempts: dict[str, int] = {}
    order: list[str] = []
    for req in requests:
        if req.id not in first:
            first[req.id] = req
            order.append(req.id)
        attempts[req.id] = attempts.get(req.id, 0) + 1
    by_id: dict[str, Any] = {}
    for resp in responses:
        by_id.setdefault(resp.id, resp)
    for resp in responses:  # answered requests whose send we never saw
        if resp.id not in first:
            first[resp.id] = resp
            attempts[resp.id] = 0
            order.append(resp.id)
    rows = []
    for seq, rid in enumerate(order):
        req = first[rid]
        resp = by_id.get(rid)
        req_attrs = dict(getattr(req, "attributes", {}) or {}) if resp is not req else {}
        if resp is None:
            rows.append(VisionRecord(seq, rid, req.event_type, _float(req.t_send_s), attempts=attempts[rid],
                                     request_attributes=req_attrs))
            continue
        attrs = dict(resp.attributes or {})
        rows.append(VisionRecord(
            seq, rid, req.event_type if resp is not req else "", _float(req.t_send_s), _float(resp.t_recv_s),
            resp.event_type, _float(attrs.get("sharpness")), _float(attrs.get("frame_t")),
            _float(attrs.get("proc_time_ms")), None if attrs.get("error") in (None, "") else str(attrs["error"]),
            attempts[rid], req_attrs, {k: v for k, v in attrs.items() if k not in _VISION_KNOWN},
            _float(attrs.get("t_trigger")), _float(attrs.get("t_exposure_start")), _float(attrs.get("exposure_ms")),
            _float(attrs.get("readout_ms")), _int(attrs.get("frame_seq")),
        ))
    return tuple(rows)


# --------------------------------------------------------------------------------------------------- writing


def _float(value: Any) -> float | None:
    if value is None or value == "":
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _int(value: Any) -> int | None:
    f = _float(value)
    return int(f) if f is not None and math.isfinite(f) else None


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)  # shortest text that parses back to the same float
    return str(value)


def _json(value: Any) -> str:
    return json.dumps(value, separators=(",", ":"), default=repr)


def _robot_row(r: RobotRecord) -> tuple[Any, ...]:
    pose = r.pose.as_tuple() if r.pose is not None else (None,) * 6
    return (r.seq, r.id, r.skill, _json(list(r.args)), r.batch, r.t_send_s, r.t_recv_s, r.t_start_s, r.t_done_s,
            r.status, *pose, r.error_code, r.error_message)


def _vision_row(v: VisionRecord) -> tuple[Any, ...]:
    return (v.seq, v.id, v.event_type, v.attempts, v.t_send_s, v.t_recv_s, v.response_type, v.sharpness,
            v.frame_t_epoch_s, v.proc_time_ms, v.error, _json(dict(v.request_attributes)),
            _json(dict(v.response_extra)), v.t_trigger_epoch_s, v.t_exposure_start_epoch_s, v.exposure_ms,
            v.readout_ms, v.frame_seq)


def _write_csv(path: Path, columns: Sequence[str], rows: Iterable[Sequence[Any]]) -> None:
    def fill(f: IO[str]) -> None:
        w = csv.writer(f)
        w.writerow(columns)
        for row in rows:
            w.writerow([_cell(c) for c in row])

    write_atomic(path, fill)


def _write_parquet(path: Path, tables: Mapping[str, tuple[Sequence[str], list[Sequence[Any]]]]
                   ) -> tuple[list[str], dict[str, str]]:
    """Parquet copies of the tables when pyarrow is installed (optional dependency); CSV stays the reference.

    Returns (files written, file -> reason not written)."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return [], {}
    written: list[str] = []
    failed: dict[str, str] = {}
    for name, (columns, rows) in tables.items():
        data = {c: [row[i] for row in rows] for i, c in enumerate(columns)}
        try:
            write_atomic(path / f"{name}.parquet", lambda f, d=data: pq.write_table(pa.table(d), f),
                         binary=True)
            written.append(f"{name}.parquet")
        except (OSError, pa.ArrowException) as exc:
            failed[f"{name}.parquet"] = _why(exc)
    return written, failed


def _iso(epoch_s: float) -> str:
    return datetime.fromtimestamp(epoch_s, tz=timezone.utc).isoformat(timespec="milliseconds")


# --------------------------------------------------------------------------------------------------- reading


def load_run(run_dir: str | os.PathLike[str]) -> Run:
    """Read a run folder written by :meth:`Recorder.save` back into plain values.

    Raises ``FileNotFoundError`` when ``run.json`` or a table is missing and ``ValueError`` when a file does not
    parse (wrong columns, bad numbers).
    """
    path = Path(run_dir)
    meta_path = path / "run.json"
    if not meta_path.is_file():
        raise FileNotFoundError(f"{path}: not a run folder (no run.json)")
    try:
        metadata = json.loads(meta_path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{meta_path}: {exc}") from exc
    robot = tuple(_parse_robot(r) for r in _read_csv(path / "robot.csv", ROBOT_COLUMNS))
    vision = tuple(_parse_vision(r) for r in _read_csv(path / "vision.csv", VISION_COLUMNS, _VISION_OPTIONAL))
    marks = tuple(Mark(int(r["seq"]), float(r["t_s"]), r["name"], json.loads(r["value"]) if r["value"] else None)
                  for r in _read_csv(path / "marks.csv", MARK_COLUMNS))
    return Run(robot, vision, marks, metadata, path)


def _read_csv(path: Path, columns: Sequence[str], optional: Sequence[str] = ()) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        missing = [c for c in columns if c not in (reader.fieldnames or ()) and c not in optional]
        if missing:
            raise ValueError(f"{path}: missing columns {missing}")
        return list(reader)


def _opt_float(text: str) -> float | None:
    return float(text) if text != "" else None


def _opt_int(text: str) -> int | None:
    return int(text) if text != "" else None


def _opt_str(text: str) -> str | None:
    return text if text != "" else None


def _parse_robot(r: dict[str, str]) -> RobotRecord:
    try:
        pose_vals = [r[c] for c in ROBOT_COLUMNS[10:16]]
        pose = Pose.from_seq(float(v) for v in pose_vals) if all(pose_vals) else None
        return RobotRecord(
            int(r["seq"]), r["id"], r["skill"], tuple(json.loads(r["args"] or "[]")), _opt_int(r["batch"]),
            _opt_float(r["t_send_s"]), _opt_float(r["t_recv_s"]), _opt_float(r["t_start_s"]),
            _opt_float(r["t_done_s"]), _opt_str(r["status"]), pose, _opt_int(r["error_code"]),
            _opt_str(r["error_message"]),
        )
    except (ValueError, json.JSONDecodeError) as exc:
        raise ValueError(f"robot.csv row {r.get('seq')!r}: {exc}") from exc


def _parse_vision(r: dict[str, str]) -> VisionRecord:
    try:
        return VisionRecord(
            int(r["seq"]), r["id"], r["event_type"], _opt_float(r["t_send_s"]), _opt_float(r["t_recv_s"]),
            _opt_str(r["response_type"]), _opt_float(r["sharpness"]), _opt_float(r["frame_t_epoch_s"]),
            _opt_float(r["proc_time_ms"]), _opt_str(r["error"]), int(r["attempts"] or 1),
            json.loads(r["request_attributes"] or "{}"), json.loads(r["response_extra"] or "{}"),
            _opt_float(r.get("t_trigger_epoch_s") or ""), _opt_float(r.get("t_exposure_start_epoch_s") or ""),
            _opt_float(r.get("exposure_ms") or ""), _opt_float(r.get("readout_ms") or ""),
            _opt_int(r.get("frame_seq") or ""),
        )
    except (ValueError, json.JSONDecodeError) as exc:
        raise ValueError(f"vision.csv row {r.get('seq')!r}: {exc}") from exc
