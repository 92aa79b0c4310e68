"""``run.mcap``: a run in MCAP with Foxglove's schemas, for the tools of the robotics world (the ``[mcap]`` extra).

Written after the run from the same records as ``robot.csv`` and ``vision.csv`` (a :class:`aioadept.runs.capture.Run`:
the :class:`~aioadept.runs.capture.Recorder`'s snapshot, or :func:`~aioadept.runs.capture.load_run` of an older folder),
so it holds exactly their messages, plus the frames the vision node saved and the robot-state messages a
:class:`StateTap` kept. Nothing is done on the protocol path: the file is written once the run is over, like the frames
of ``run.rrd``. Topics (times are wall clock, epoch ns; the loop-clock stamps are shifted by ``start_wall_epoch_s -
start_loop_s`` as in ``run.rrd``):

=====================  =================================  ==================================================
``/robot/command``     ``foxglove.Log``                   every command sent (one per ``robot.csv`` row)
``/robot/ack``         ``foxglove.Log``                   every ack (one per acked row; WARNING when not done)
``/robot/state``       ``aioadept.RobotState`` (bus's)    every sample of the robot's state stream, raw
``/tf``                ``foxglove.FrameTransform``        the arm: each link in its parent (URDF names), from
                                                          the state's joints (25 per second); without a state
                                                          stream at every acked pose (inverse kinematics)
``/vision/request``    ``epypes.Event`` (the bus's own)   every vision request (one per ``vision.csv`` row)
``/vision/response``   ``epypes.Event`` (the bus's own)   every response (one per answered row)
``/camera/image``      ``foxglove.CompressedImage``       each frame that answered a request, the PNG as saved
=====================  =================================  ==================================================

The URDF of the run's robot model (:func:`aioadept.robots.urdf.urdf`, whose link names ``/tf`` uses; the model is its
parameters' ``cell.robot.model``, :func:`aioadept.record.model.run_model`) twice: on ``/robot_description`` as ROS 2
publishes it (``std_msgs/msg/String`` in CDR: Foxglove's 3D panel and Rerun's MCAP reader draw the arm from it), and as
the attachment ``<model>.urdf`` (``viper_s850.urdf``, ``cobra_s600.urdf``, ...: :func:`urdf_name`); metadata
``aioadept`` (version, start time, the run's parameters, the robot model). Like ``run.rrd``, the file is written under a
temporary name and renamed into place only when complete: a full disk leaves no ``run.mcap`` at all."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import struct
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["MAX_STATE_SAMPLES", "MCAP_INSTALL_HINT", "TF_RATE_HZ", "URDF_ATTACHMENT", "StateTap", "mcap_available",
           "ros2_string_cdr", "urdf_name", "write_run_mcap"]

MCAP_INSTALL_HINT = ("run.mcap needs the optional MCAP packages: pip install 'aioadept[mcap]' "
                     "(or: pip install mcap==1.6.0 mcap-protobuf-support==0.6.0 foxglove-schemas-protobuf==0.4.0)")
URDF_ATTACHMENT = "viper_s850.urdf"
"""The attachment of a run on the default arm (:func:`urdf_name`)."""


def urdf_name(arm: Any) -> str:
    """The URDF attachment's file name of the robot model ``arm``: ``viper_s850.urdf``, ``cobra_s600.urdf``, ..."""
    return arm.name.replace("-", "_") + ".urdf"


log = logging.getLogger(__name__)

# vision.csv's own columns back to the response attribute they came from (aioadept.runs.capture._VISION_KNOWN).
_RESPONSE_FIELDS = (("sharpness", "sharpness"), ("frame_t_epoch_s", "frame_t"), ("proc_time_ms", "proc_time_ms"),
                    ("error", "error"), ("t_trigger_epoch_s", "t_trigger"),
                    ("t_exposure_start_epoch_s", "t_exposure_start"), ("exposure_ms", "exposure_ms"),
                    ("readout_ms", "readout_ms"), ("frame_seq", "frame_seq"))


MAX_STATE_SAMPLES = 200_000
"""At most this many robot-state messages are kept for one ``run.mcap`` (over half an hour of the sim's 100 Hz,
~20 MB): a run left going for hours must not grow the application's memory without bound."""

TF_RATE_HZ = 25.0
"""Arm poses (``/tf``) drawn per second from the state stream, as :data:`aioadept.record.live.STATE_RATE_HZ`; the
raw ``/robot/state`` keeps every sample."""


class StateTap:
    """Keeps the raw ``robot.state`` messages of one run for ``run.mcap``: a SUB socket on the event loop that only
    appends the payload to a list (no decoding there: that is done after the run, by :func:`write_run_mcap`)."""

    def __init__(self, endpoint: str) -> None:
        self.endpoint = endpoint
        self.payloads: list[bytes] = []
        self.dropped = 0
        self._task: Any = None

    def start(self) -> StateTap:
        import asyncio

        self._task = asyncio.get_running_loop().create_task(self._follow(), name="mcap-state")
        return self

    async def stop(self) -> list[bytes]:
        """Stop listening; the payloads kept."""
        import asyncio

        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
            self._task = None
        return self.payloads

    async def _follow(self) -> None:
        from aioadept.bus.messages import ROBOT_STATE_TOPIC
        from aioadept.bus.pubsub import Subscriber

        try:
            sub = Subscriber(self.endpoint, topics=[ROBOT_STATE_TOPIC], rcvhwm=256)
        except Exception as exc:  # noqa: BLE001 - no state stream: run.mcap draws the arm from the acks
            log.warning("run.mcap: cannot follow the robot state at %s (%s)", self.endpoint, exc)
            return
        try:
            while True:
                _topic, payload = await sub.recv()
                if len(self.payloads) < MAX_STATE_SAMPLES:
                    self.payloads.append(bytes(payload))
                else:
                    self.dropped += 1
        finally:
            with contextlib.suppress(Exception):
                sub.close()


def mcap_available() -> bool:
    """True when the ``[mcap]`` extra imports."""
    try:
        import foxglove_schemas_protobuf  # noqa: F401
        import mcap_protobuf  # noqa: F401
    except ImportError:
        return False
    return True


def _ns(epoch_s: float) -> int:
    return int(round(epoch_s * 1e9))


def _stamp(msg_field: Any, epoch_s: float) -> None:
    msg_field.FromNanoseconds(_ns(epoch_s))


def _event(event_type: str, event_id: str, attributes: Mapping[str, Any]) -> Any:
    """The bus's ``epypes.Event`` for a request or response; a value the schema cannot carry is kept as text."""
    from aioadept.bus.messages import BusEncodeError, event_to_pb

    attrs = {k: v for k, v in attributes.items() if v is not None}
    try:
        return event_to_pb(event_type, event_id, attrs)
    except BusEncodeError:
        return event_to_pb(event_type, event_id,
                           {k: v if isinstance(v, (str, float, int)) and not isinstance(v, bool) else json.dumps(v)
                            for k, v in attrs.items()})


def _tf(out: list[tuple[int, str, Any]], t_epoch: float, arm: Any, joints_deg: Any) -> None:
    from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform

    from aioadept.robots.urdf import link_transforms, quaternion_xyzw

    for parent, child, trans, rot in link_transforms(arm, joints_deg):
        ft = FrameTransform(parent_frame_id=parent, child_frame_id=child)
        _stamp(ft.timestamp, t_epoch)
        ft.translation.x, ft.translation.y, ft.translation.z = (float(v) for v in trans)
        ft.rotation.x, ft.rotation.y, ft.rotation.z, ft.rotation.w = quaternion_xyzw(rot)
        out.append((_ns(t_epoch), "/tf", ft))


class _Raw:
    """A message already serialised (a ``robot.state`` payload as it came off the bus) with its Protobuf class."""

    def __init__(self, cls: Any, data: bytes) -> None:
        self.cls, self.data = cls, data

    def SerializeToString(self) -> bytes:  # noqa: N802 - the Protobuf name the writer calls
        return self.data


def _state_messages(payloads: list[bytes], out: list[tuple[int, str, Any]], arm: Any) -> bool:
    """``/robot/state`` (every payload, raw) and ``/tf`` at most :data:`TF_RATE_HZ` (plus the last sample and every
    start and stop of a motion) from the state stream; False when it gave no joints of ``arm`` (draw from the acks
    then)."""
    from aioadept.bus import aioadept_pb2
    from aioadept.bus.messages import RobotState

    states = []
    for data in payloads:
        try:
            states.append((RobotState.from_bytes(data), data))
        except Exception:  # noqa: BLE001 - a stranger's message on the topic: not this robot's state
            continue
    states.sort(key=lambda s: s[0].wall_time_s)
    last_t, last_motion = -1e18, None
    for i, (st, data) in enumerate(states):
        out.append((_ns(st.wall_time_s), "/robot/state", _Raw(aioadept_pb2.RobotState, data)))
        final = i == len(states) - 1
        if len(st.joints_deg) == arm.dof and (st.wall_time_s - last_t >= 1.0 / TF_RATE_HZ
                                              or st.in_motion != last_motion or final):
            last_t, last_motion = st.wall_time_s, st.in_motion
            _tf(out, st.wall_time_s, arm, st.joints_deg)
    return any(len(st.joints_deg) == arm.dof for st, _d in states)


def _messages(run: Any, frames_dir: Path | None, frame_wait_s: float,
              state: list[bytes] | None = None) -> list[tuple[int, str, Any]]:
    """(log time ns, topic, Protobuf message) of the run, in no particular order."""
    from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
    from foxglove_schemas_protobuf.Log_pb2 import Log

    from aioadept.record.model import joints_from_pose, run_model
    from aioadept.record.rrd import frame_file

    md = run.metadata
    arm = run_model(md)
    shift = float(md.get("start_wall_epoch_s", 0.0)) - float(md.get("start_loop_s", 0.0))
    out: list[tuple[int, str, Any]] = []
    # The arm: from the robot's own state stream when there was one, else from the acked poses.
    arm_from_acks = not _state_messages(state or [], out, arm)
    joints: tuple[float, ...] = tuple(arm.home_deg)

    def log(topic: str, t_epoch: float, level: int, text: str) -> None:
        m = Log(level=level, message=text, name="robot")
        _stamp(m.timestamp, t_epoch)
        out.append((_ns(t_epoch), topic, m))

    for r in run.robot:
        if r.t_send_s is not None:
            args = " ".join(f"{a:g}" for a in r.args)
            log("/robot/command", r.t_send_s + shift, Log.INFO, f"-> {r.id} {r.skill} {args}".rstrip())
        if r.t_recv_s is None:
            continue
        t = r.t_recv_s + shift
        text = f"<- {r.id} {r.skill} {r.status or ''}"
        if r.pose is not None:
            p = r.pose
            text += f" pose {p.x:.3f} {p.y:.3f} {p.z:.3f} {p.yaw:.3f} {p.pitch:.3f} {p.roll:.3f}"
        if r.error_message:
            text += f" error {r.error_code}: {r.error_message}"
        log("/robot/ack", t, Log.INFO if r.status == "done" else Log.WARNING, text)
        if arm_from_acks and r.pose is not None and r.status == "done":
            q = joints_from_pose(r.pose, joints, arm)
            if q is None:
                continue  # out of reach or a jump: the arm stays where it was last drawn
            joints = q
            _tf(out, t, arm, joints)

    wait_s = frame_wait_s
    for v in run.vision:
        if v.t_send_s is not None:
            out.append((_ns(v.t_send_s + shift), "/vision/request",
                        _event(v.event_type, v.id, v.request_attributes)))
        if v.t_recv_s is None:
            continue
        attrs = {**v.response_extra, **{attr: getattr(v, col) for col, attr in _RESPONSE_FIELDS}}
        out.append((_ns(v.t_recv_s + shift), "/vision/response", _event(v.response_type or "", v.id, attrs)))
        if frames_dir is None or v.frame_seq is None or v.error:
            continue
        camera = str(v.response_extra.get("camera", ""))
        path = frame_file(frames_dir, camera, v.frame_seq)
        # The node saves a frame after answering (off its response path): wait a little for the first one missing;
        # a node that saves nothing costs one wait only.
        deadline = time.monotonic() + wait_s
        while not path.is_file() and time.monotonic() < deadline:
            time.sleep(0.005)
        if not path.is_file():
            wait_s = 0.0
            continue
        t_frame = v.frame_t_epoch_s if v.frame_t_epoch_s is not None else v.t_recv_s + shift
        img = CompressedImage(frame_id=camera or "camera", data=path.read_bytes(), format="png")
        _stamp(img.timestamp, t_frame)
        out.append((_ns(t_frame), "/camera/image", img))
    return out


def ros2_string_cdr(text: str) -> bytes:
    """A ROS 2 ``std_msgs/msg/String`` in CDR (little endian): the 4-byte encapsulation header, then the string as
    a uint32 length that counts its NUL terminator, its UTF-8 bytes and the NUL."""
    data = text.encode()
    return b"\x00\x01\x00\x00" + struct.pack("<I", len(data) + 1) + data + b"\x00"


def write_run_mcap(run: Any, path: str | os.PathLike[str], *, frames_dir: str | os.PathLike[str] | None = None,
                   frame_wait_s: float = 5.0, state: list[bytes] | None = None) -> str | None:
    """Write ``run`` (a :class:`aioadept.runs.capture.Run`) to ``path`` (``run.mcap``); None when written, else why not
    (then no file is left under ``path``, nor under its temporary name). Never raises for a write error: the
    caller names the file in ``run.json``'s ``not_written``. ``frames_dir``: where the vision node saved its
    frames (``<camera>_<seq>.png``); ``frame_wait_s``: how long to wait for the first frame file not yet there;
    ``state``: the raw ``robot.state`` payloads of the run (:class:`StateTap`), if any."""
    from mcap.writer import Writer
    from mcap_protobuf.schema import register_schema

    from aioadept import __version__
    from aioadept.record.model import run_model
    from aioadept.robots.urdf import urdf

    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    msgs = _messages(run, None if frames_dir is None else Path(frames_dir), frame_wait_s, state)
    msgs.sort(key=lambda m: m[0])  # readers expect log times in order (stable: a link chain keeps its order)
    md = run.metadata
    start_ns = _ns(float(md.get("start_wall_epoch_s", time.time())))
    arm = run_model(md)
    description = urdf(arm)
    try:
        with open(tmp, "wb") as f:
            w = Writer(f)
            w.start(profile="", library=f"aioadept/{__version__}")
            w.add_attachment(create_time=start_ns, log_time=start_ns, name=urdf_name(arm),
                             media_type="application/xml", data=description.encode())
            w.add_metadata("aioadept", {
                "aioadept_version": __version__, "start_wall_epoch_s": repr(md.get("start_wall_epoch_s")),
                "parameters": json.dumps(md.get("parameters") or {}, default=repr), "robot_model": arm.name,
            })
            # The robot description as ROS 2 publishes it (std_msgs/String on robot_description): Foxglove's 3D
            # panel and Rerun's MCAP reader both draw the URDF from it, posed by /tf.
            sid = w.register_schema(name="std_msgs/msg/String", encoding="ros2msg", data=b"string data")
            cid = w.register_channel(topic="/robot_description", message_encoding="cdr", schema_id=sid)
            w.add_message(channel_id=cid, log_time=start_ns, publish_time=start_ns, data=ros2_string_cdr(description))
            channels: dict[str, int] = {}
            seq: dict[str, int] = {}
            for t_ns, topic, msg in msgs:
                if topic not in channels:
                    channels[topic] = w.register_channel(topic=topic, message_encoding="protobuf",
                                                         schema_id=register_schema(w, getattr(msg, "cls", type(msg))))
                seq[topic] = seq.get(topic, 0) + 1
                w.add_message(channel_id=channels[topic], log_time=t_ns, publish_time=t_ns,
                              data=msg.SerializeToString(), sequence=seq[topic])
            w.finish()
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        return exc.strerror or str(exc)
    return None
