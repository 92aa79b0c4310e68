"""What a run looks like in Rerun: one :class:`CellLogger` turns the run's events into Rerun entities.

Both ways of making a ``run.rrd`` go through here: :class:`aioadept.record.RunRecording` feeds it live (from the
client and Communicator hooks, the sim's state stream and the vision node's saved frames, on its own thread), and
:func:`aioadept.record.rrd_from_run` feeds it an older run folder's CSV logs after the fact. So a live run and its
rebuild from CSV show the same entities.

Every event is placed on the timeline ``time`` (wall clock, epoch seconds: the loop-clock stamps of the hooks are
shifted by the run's ``start_wall_epoch_s - start_loop_s``); the sharpness and the frames are also on ``step``
(the index of the focus step). Entities (units: mm, degrees, ms):

===============================  ===========================================================================
``world``                        static: right-handed, Z up (robot base frame, mm)
``world/robot/links``            the arm as a line strip base -> each joint's axis -> flange (the run's robot model)
``world/robot/joints``           the same points, labelled with the URDF's joint names
``robot/urdf``                   static: the model's URDF (the arm the run used, as ``run.mcap`` carries it)
``world/robot/tool``             the tool frame (Transform3D + axes), from the acked pose
``world/targets``                every commanded target so far (points), ``world/target`` the latest (frame)
``world/focus_plane``            the focus plane once found: a thin plate at the sharpest tool pose
``robot/joints_deg``             the joint values (one series per joint, named as the URDF's joints; a Cobra's J3 mm)
``messages/robot``               every command (``->``) and ack (``<-``) as a text log entry
``messages/vision``              every vision request and response as a text log entry
``timeline/robot_in_flight``     commands sent and not yet acked (a step curve: the Gantt chart's robot row)
``timeline/vision_in_flight``    vision requests not yet answered (the Gantt chart's vision row)
``timeline/robot_ack_ms``        time from send to ack of each command
``timeline/vision_response_ms``  time from request to response
``camera/image``                 each processed frame, downsampled, at its exposure time ``frame_t``
``camera/frame_age_ms``          request time minus exposure time of the frame that answered it
``focus/sharpness``              the sharpness after each step, at the frame's exposure time
``focus/plane_offset_mm``        distance of the focus plane from the approach pose along tool z, once found
===============================  ===========================================================================

A :class:`CellLogger` is used from one thread at a time (Rerun keeps the current time per thread).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aioadept.geometry import Pose, rel_tool
from aioadept.record.model import chain_labels, chain_points_mm, joints_from_pose
from aioadept.robots import RobotModel, model
from aioadept.robots.base import model_joints
from aioadept.robots.urdf import urdf

__all__ = ["APP_ID", "IMAGE_MAX_WIDTH", "CellLogger", "FrameRef", "default_blueprint", "frame_file"]

APP_ID = "aioadept"
IMAGE_MAX_WIDTH = 320
"""Frames wider than this are halved until they fit: the viewer shows a thumbnail of what the node processed."""

_TOOL_AXIS_MM = 60.0
_PLATE_HALF_MM = (60.0, 60.0, 0.5)
_MOTION_SKILLS = {"move_to", "move_joints", "move_rel_world", "move_rel_tool", "move_rel_joints"}


@dataclass(frozen=True, slots=True)
class FrameRef:
    """A frame the vision node saved (``--save-frames``): file, exposure time (epoch s), camera, sequence."""

    path: Path
    t_epoch_s: float
    camera: str
    seq: int
    step: int | None = None


def default_blueprint() -> Any:
    """The viewer's layout for a run (sent with every ``run.rrd`` and live stream; the user may rearrange it).

    Left, large: the cell in 3D (arm, tool, targets, focus plane) above the message log (robot and vision traffic
    and the app's marks). Right: what the camera saw, the sharpness after each step, the Gantt chart's rows as
    commands and requests in flight, the latencies, and the joint angles. Without it Rerun picks an automatic grid
    in which the 3D view and the camera get a small tile each.
    """
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                # Looking at the arm and the work area in front of it (the demo's focus plane is ~600 mm out, low)
                # from the front right, instead of from far enough to see the whole scene's bounding box.
                rrb.Spatial3DView(name="Cell (base frame, mm)", origin="world",
                                  eye_controls=rrb.EyeControls3D(position=(650.0, -1050.0, 650.0),
                                                                 look_target=(-150.0, -300.0, 300.0),
                                                                 eye_up=(0.0, 0.0, 1.0))),
                rrb.TextLogView(name="Messages", origin="messages"),
                row_shares=[3, 2],
            ),
            rrb.Vertical(
                rrb.Spatial2DView(name="Camera", origin="camera/image"),
                rrb.TimeSeriesView(name="Sharpness", origin="focus/sharpness"),
                rrb.TimeSeriesView(name="In flight (Fig. 10 rows)", origin="timeline",
                                   contents=["$origin/robot_in_flight", "$origin/vision_in_flight"],
                                   plot_legend=rrb.PlotLegend(rrb.Corner2D.LeftTop)),
                rrb.TimeSeriesView(name="Latency (ms)", origin="/",
                                   contents=["timeline/robot_ack_ms", "timeline/vision_response_ms",
                                             "camera/frame_age_ms"],
                                   plot_legend=rrb.PlotLegend(rrb.Corner2D.LeftTop)),
                rrb.TimeSeriesView(name="Joints (deg)", origin="robot/joints_deg",
                                   plot_legend=rrb.PlotLegend(visible=False)),
                row_shares=[3, 2, 1, 1, 1],
            ),
            column_shares=[3, 2],
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"),
    )


def frame_file(frames_dir: Path, camera: str, seq: int) -> Path:
    """The file name :class:`aioadept.vision.sources.FrameRecorder` gives a frame (``<camera>_<seq:06d>.png``)."""
    return frames_dir / f"{camera.replace(':', '_').replace('/', '_')}_{int(seq):06d}.png"


def _skill_text(skill: str, args: Sequence[Any]) -> str:
    return f"{skill}({', '.join(f'{a:g}' if isinstance(a, float) else str(a) for a in args)})"


class CellLogger:
    """Logs a run's events into a Rerun recording stream ``rec`` (see the module docstring for the entities).

    ``loop_to_epoch_s``: added to loop-clock stamps (client and Communicator records, marks) to get epoch seconds.
    ``arm``: the robot model the run used (default: the Viper s850): the arm drawn, its URDF and joint names.
    """

    def __init__(self, rec: Any, *, loop_to_epoch_s: float = 0.0, arm: RobotModel | None = None) -> None:
        import rerun as rr

        self.rr = rr
        self.rec = rec
        self.offset = loop_to_epoch_s
        self.arm = model() if arm is None else arm
        self._labels = chain_labels(self.arm)
        self._robot_in_flight = 0
        self._vision_in_flight = 0
        self._sent: dict[str, tuple[str, float]] = {}  # command id -> (skill, t_send epoch)
        self._requested: dict[str, float] = {}
        self.joints: tuple[float, ...] = tuple(self.arm.home_deg)
        self.pose: Pose | None = None
        self._have_state = False
        self._targets: list[tuple[float, float, float]] = []
        self._step = 0
        self._steps: list[tuple[float, Pose | None]] = []  # (sharpness, pose at that step)
        self._approach: Pose | None = None
        self.counts: dict[str, int] = {}
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        rec.log("world/base", rr.Boxes3D(centers=[(0.0, 0.0, -10.0)], half_sizes=[(120.0, 120.0, 10.0)],
                                         colors=[(90, 90, 90)]), static=True)
        rec.log("robot/urdf", rr.TextDocument(urdf(self.arm), media_type=rr.MediaType.TEXT), static=True)
        rec.log("robot/joints_deg", rr.SeriesLines(names=[j.name for j in self.arm.urdf_joints]), static=True)

    # ------------------------------------------------------------------------------------------------ helpers
    def _at(self, t_epoch_s: float | None) -> bool:
        if t_epoch_s is None or not math.isfinite(t_epoch_s):
            return False
        self.rec.set_time("time", timestamp=t_epoch_s)
        return True

    def _count(self, name: str) -> None:
        self.counts[name] = self.counts.get(name, 0) + 1

    def _in_flight(self, lane: str, before: int, after: int) -> None:
        # Both values at the same instant: the series draws a vertical edge, a step curve like a Gantt row.
        rr = self.rr
        self.rec.log(f"timeline/{lane}_in_flight", rr.Scalars(float(before)))
        self.rec.log(f"timeline/{lane}_in_flight", rr.Scalars(float(after)))

    # ------------------------------------------------------------------------------------------------ robot
    def command(self, cid: str, skill: str, args: Sequence[Any], t_send_loop_s: float | None) -> None:
        """A command message was written (``on_send``)."""
        t = None if t_send_loop_s is None else t_send_loop_s + self.offset
        if not self._at(t):
            return
        self._count("command")
        rr = self.rr
        self._sent[cid] = (skill, t)  # type: ignore[assignment]
        self.rec.log("messages/robot", rr.TextLog(f"-> {cid} {_skill_text(skill, args)}", level="DEBUG"))
        self._in_flight("robot", self._robot_in_flight, self._robot_in_flight + 1)
        self._robot_in_flight += 1
        target = self._target(skill, args)
        if target is not None:
            self._targets.append(tuple(target.position_mm))
            self.rec.log("world/targets", rr.Points3D(self._targets, radii=3.0, colors=[(255, 170, 0)]))
            self.rec.log("world/target", rr.Transform3D(translation=target.position_mm,
                                                         mat3x3=target.to_matrix()[:3, :3]))
            self.rec.log("world/target", rr.TransformAxes3D(axis_length=_TOOL_AXIS_MM / 2))

    def _target(self, skill: str, args: Sequence[Any]) -> Pose | None:
        line = self._line_target(skill, args)
        if line is not None:
            return line
        if skill not in _MOTION_SKILLS or len(args) != 6:
            return None
        vals = [float(a) for a in args]
        try:
            if skill == "move_to":
                return Pose.from_seq(vals)
            if skill == "move_joints":
                return self.arm.forward(model_joints(self.arm.name, self.arm.dof, vals))
            if skill == "move_rel_joints":
                rel = model_joints(self.arm.name, self.arm.dof, vals)
                return self.arm.forward([a + b for a, b in zip(self.joints, rel, strict=True)])
            if self.pose is None:
                return None
            if skill == "move_rel_tool":
                return rel_tool(self.pose, vals)
            from aioadept.geometry import rel_world

            return rel_world(self.pose, vals)
        except (ValueError, ArithmeticError):
            return None

    def _line_target(self, skill: str, args: Sequence[Any]) -> Pose | None:
        """The target of a straight-line or approach skill (docs/protocol.md 4.3.1), else None. An
        approach or depart distance d is along -Z of the tool (V+ ``APPRO``/``DEPART``): ``pose:TRANS(0,0,-d)``."""
        try:
            vals = [float(a) for a in args]
            if skill == "move_to_s" and len(vals) == 6:
                return Pose.from_seq(vals)
            if skill in ("appro", "appros") and len(vals) == 7:
                return rel_tool(Pose.from_seq(vals[:6]), (0.0, 0.0, -vals[6], 0.0, 0.0, 0.0))
            if self.pose is None:
                return None
            if skill == "move_rel_tool_s" and len(vals) == 6:
                return rel_tool(self.pose, vals)
            if skill in ("depart", "departs") and len(vals) == 1:
                return rel_tool(self.pose, (0.0, 0.0, -vals[0], 0.0, 0.0, 0.0))
        except (ValueError, ArithmeticError):
            return None
        return None

    def ack(self, cid: str, skill: str, status: str | None, pose: Pose | None, t_recv_loop_s: float | None, *,
            t_send_loop_s: float | None = None, error: str | None = None) -> None:
        """The ack of command ``cid`` arrived (``on_ack``)."""
        t = None if t_recv_loop_s is None else t_recv_loop_s + self.offset
        if not self._at(t):
            return
        self._count("ack")
        rr = self.rr
        sent = self._sent.pop(cid, None)
        t_send = sent[1] if sent else (None if t_send_loop_s is None else t_send_loop_s + self.offset)
        dur = "" if t_send is None else f" {1e3 * (t - t_send):.1f} ms"  # type: ignore[operator]
        level = "INFO" if status in (None, "done") else "WARN"
        text = f"<- {cid} {skill} {status or '?'}{dur}"
        if error:
            text += f": {error}"
        self.rec.log("messages/robot", rr.TextLog(text, level=level))
        if sent is not None or t_send is not None:
            after = max(0, self._robot_in_flight - 1)
            self._in_flight("robot", self._robot_in_flight, after)
            self._robot_in_flight = after
        if t_send is not None:
            self.rec.log("timeline/robot_ack_ms", rr.Scalars(1e3 * (t - t_send)))  # type: ignore[operator]
        if pose is not None:
            self.pose = pose
            self._tool(pose)
            if not self._have_state:  # no state stream: the arm from the acked pose
                joints = joints_from_pose(pose, self.joints, self.arm)
                if joints is not None:
                    self._arm(joints)

    def _tool(self, pose: Pose) -> None:
        rr = self.rr
        self.rec.log("world/robot/tool", rr.Transform3D(translation=pose.position_mm,
                                                         mat3x3=pose.to_matrix()[:3, :3]))
        self.rec.log("world/robot/tool", rr.TransformAxes3D(axis_length=_TOOL_AXIS_MM))

    def _arm(self, joints: Sequence[float]) -> None:
        rr = self.rr
        self.joints = tuple(float(j) for j in joints)
        pts = chain_points_mm(self.joints, self.arm)
        self.rec.log("world/robot/links", rr.LineStrips3D([pts], radii=12.0, colors=[(70, 130, 200)]))
        self.rec.log("world/robot/joints", rr.Points3D(pts, radii=18.0, labels=self._labels,
                                                        colors=[(230, 230, 230)]))
        self.rec.log("robot/joints_deg", rr.Scalars(self.joints))

    def state(self, wall_time_s: float, joints_deg: Sequence[float], pose: Pose | None = None) -> None:
        """A sample of the sim's robot-state stream: the arm from its joint angles."""
        if not self._at(wall_time_s):
            return
        if len(joints_deg) != self.arm.dof:  # another arm's stream: not drawn as this one
            self._count("state_other_arm")
            return
        self._count("state")
        self._have_state = True
        self._arm(joints_deg)
        if pose is not None:
            self.pose = pose
            self._tool(pose)

    # ------------------------------------------------------------------------------------------------ vision
    def request(self, rid: str, event_type: str, attributes: Mapping[str, Any], t_send_loop_s: float | None) -> None:
        """A vision request was published (``on_request``)."""
        t = None if t_send_loop_s is None else t_send_loop_s + self.offset
        if not self._at(t):
            return
        self._count("request")
        rr = self.rr
        self._requested[rid] = t  # type: ignore[assignment]
        attrs = json.dumps(dict(attributes), default=repr, separators=(",", ":")) if attributes else ""
        self.rec.log("messages/vision", rr.TextLog(f"-> {rid} {event_type} {attrs}".rstrip(), level="DEBUG"))
        self._in_flight("vision", self._vision_in_flight, self._vision_in_flight + 1)
        self._vision_in_flight += 1

    def response(self, rid: str, event_type: str | None, attributes: Mapping[str, Any], t_recv_loop_s: float | None,
                 *, t_send_loop_s: float | None = None) -> None:
        """The response to request ``rid`` arrived (``on_response``): text, span end, sharpness."""
        t = None if t_recv_loop_s is None else t_recv_loop_s + self.offset
        if not self._at(t):
            return
        self._count("response")
        rr = self.rr
        t_send = self._requested.pop(rid, None)
        if t_send is None and t_send_loop_s is not None:
            t_send = t_send_loop_s + self.offset
        err = attributes.get("error")
        s = attributes.get("sharpness")
        dur = "" if t_send is None else f" {1e3 * (t - t_send):.1f} ms"  # type: ignore[operator]
        what = f"error: {err}" if err else (f"sharpness={float(s):.3f}" if s is not None else "")
        self.rec.log("messages/vision", rr.TextLog(f"<- {rid} {event_type or '?'}{dur} {what}".rstrip(),
                                                   level="WARN" if err else "INFO"))
        if t_send is not None:
            after = max(0, self._vision_in_flight - 1)
            self._in_flight("vision", self._vision_in_flight, after)
            self._vision_in_flight = after
            self.rec.log("timeline/vision_response_ms", rr.Scalars(1e3 * (t - t_send)))  # type: ignore[operator]
        age = attributes.get("frame_age_ms")
        if isinstance(age, (int, float)) and math.isfinite(age):
            self.rec.log("camera/frame_age_ms", rr.Scalars(float(age)))
        if s is not None and not err:
            frame_t = attributes.get("frame_t")
            t_frame = float(frame_t) if isinstance(frame_t, (int, float)) and math.isfinite(frame_t) else t
            self._sharpness(float(s), t_frame)  # type: ignore[arg-type]

    def _sharpness(self, s: float, t_frame: float) -> None:
        rr = self.rr
        self._at(t_frame)
        self.rec.set_time("step", sequence=self._step)
        self.rec.log("focus/sharpness", rr.Scalars(s))
        self.rec.reset_time()
        if not self._steps:
            self._approach = self.pose
        self._steps.append((s, self.pose))
        self._step += 1
        self._count("sharpness")

    def frame(self, image: np.ndarray, t_epoch_s: float, *, step: int | None = None, camera: str = "") -> None:
        """A processed camera frame (mono8 or BGR), at its exposure time; downsampled to :data:`IMAGE_MAX_WIDTH`."""
        if not self._at(t_epoch_s):
            return
        rr = self.rr
        if step is not None:
            self.rec.set_time("step", sequence=step)
        img = image
        while img.shape[1] > IMAGE_MAX_WIDTH:
            img = img[::2, ::2]
        img = np.ascontiguousarray(img)
        self.rec.log("camera/image", rr.Image(img, color_model="L" if img.ndim == 2 else "BGR")
                     .compress(jpeg_quality=85))
        if step is not None:
            self.rec.reset_time()
        self._count("frame")

    # ------------------------------------------------------------------------------------------------ focus
    def mark(self, name: str, value: Any, t_loop_s: float, *, plane: bool = True) -> None:
        """A mark of the application (``recorder.mark``): ``retract`` means the sharpness peak was passed, and
        (``plane``) the focus plane is drawn at the pose of the sharpest step."""
        if not self._at(t_loop_s + self.offset):
            return
        self._count("mark")
        self.rec.log("messages/app", self.rr.TextLog(f"{name} {'' if value is None else value}".rstrip()))
        if plane and name == "retract" and self._steps:
            sharp = [s for s, _ in self._steps]
            peak = max(range(len(sharp)), key=sharp.__getitem__)
            pose = self._steps[peak][1]
            if pose is not None:
                self.focus_plane(pose, offset_mm=self._offset(pose))

    def _offset(self, pose: Pose) -> float | None:
        if self._approach is None:
            return None
        return float(np.linalg.norm(pose.position_mm - self._approach.position_mm))

    def focus_plane(self, pose: Pose, *, offset_mm: float | None = None, t_epoch_s: float | None = None) -> None:
        """The focus plane found: a thin plate perpendicular to tool z at the sharpest pose."""
        if t_epoch_s is not None:
            self._at(t_epoch_s)
        rr = self.rr
        m = pose.to_matrix()
        w, x, y, z = _quaternion_wxyz(m[:3, :3])
        self.rec.log("world/focus_plane", rr.Boxes3D(centers=[pose.position_mm], half_sizes=[_PLATE_HALF_MM],
                                                     quaternions=[rr.Quaternion(xyzw=[x, y, z, w])],
                                                     colors=[(0, 200, 120, 120)], labels=["focus plane"],
                                                     fill_mode="solid"))
        if offset_mm is not None:
            self.rec.log("focus/plane_offset_mm", rr.Scalars(offset_mm))
        self.rec.log("messages/app", rr.TextLog(
            f"focus plane at x={pose.x:.2f} y={pose.y:.2f} z={pose.z:.2f} mm"
            + ("" if offset_mm is None else f", {offset_mm:.2f} mm from the approach pose"), level="INFO"))
        self._count("focus_plane")


def _quaternion_wxyz(r: np.ndarray) -> tuple[float, float, float, float]:
    """Unit quaternion of a rotation matrix (Shepperd's method: stable for every rotation)."""
    tr = float(np.trace(r))
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        return 0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s
    i = int(np.argmax(np.diag(r)))
    if i == 0:
        s = math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2]) * 2
        return (r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s
    if i == 1:
        s = math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2]) * 2
        return (r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s
    s = math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1]) * 2
    return (r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s
