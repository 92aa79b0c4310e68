"""The V+ emulator's robot: V+ motion instructions on the one simulated controller.

The interpreter's robot instructions (``ATTACH ()``, ``MOVE``, ``MOVES``, ``APPRO``, ``DEPART``, ``BREAK``,
``SPEED``, ``HERE``, ``TOOL``, ``INRANGE``, ``DELAY``, ``BRAKE``, ``DRY.RUN``) call a :class:`RobotDevice`. It
wraps :class:`aioadept.sim.controller.Controller` - the same kinematics, motion timing, forward processing,
speed rules, time scale and state stream as the Python sim - and adds only what V+ has and the skill table has
not: ownership by a task, transformations and precision points, INRANGE, DRY.RUN, and V+ error codes. There is
no second motion model here: every motion goes through ``Controller.move_pose`` / ``Controller.move_joints`` /
``Controller.wait_rest``, so fixes there (one-motion-deep forward processing, kinematics) apply here too.

Time: all times are server seconds. Motion methods are generators, like the controller's skill generators: each
``yield`` gives the time the instruction wants to be resumed at; the interpreter sets :attr:`RobotDevice.now_s`
to the time of the resumption (never earlier than before) and calls ``next()`` again. They are generator
functions: nothing happens, not even a check, until the first ``next()``, which raises
:class:`VPlusRobotError` for a V+ robot error::

    robot = RobotDevice(Controller(time_scale=10))
    robot.now_s = 0.0
    robot.attach(task=1)
    gen = robot.move(1, trans(400, 0, 500, 0, 180, 0))
    for wake in gen:              # forward processing: a first MOVE returns at once (no yield)
        robot.now_s = wake
    ...
    for wake in robot.break_():   # BREAK: resumed when the arm is at rest
        robot.now_s = wake

Choices where the V+ manuals are silent (docs/vplus.md lists them):

- ``MOVES``, ``APPROS``, ``DEPARTS`` follow a straight line (the controller's one straight-line model); a line
  that would leave the workspace, pass a joint limit or cross a singularity part-way is refused before the arm
  moves, with the error of the first sample that fails (V+ checks during the motion; UNCONFIRMED which codes).
- ``BRAKE`` (any task, attached or not) decelerates the arm to rest, drops planned motions, and also drops a
  motion instruction that is waiting for its turn at that moment: it returns without moving. No motion that was
  waiting when the brake came starts afterwards.
- ``DEPART`` and ``APPRO`` relative to HERE start from where the planned motions end (the start of the new
  motion), not from where the arm is at that instant.
- ``DELAY`` waits for the arm to be at rest and then holds the program for the delay (divided by the time scale,
  as every motion time is); V+ lets the program run on during a DELAY motion.
- ``DRY.RUN``: motion instructions check their target (errors are raised as without DRY.RUN), consume a one-shot
  SPEED, and complete at once without moving.
- ``SPEED`` accepts values above 0; above 100 is taken as 100 by the controller's cap.
"""

from __future__ import annotations

import math
from collections.abc import Generator, Hashable
from dataclasses import dataclass
from typing import Union

from aioadept.errors import RobotError
from aioadept.geometry import Pose, inverse_transform
from aioadept.protocol import ErrorCode
from aioadept.robots.base import JointLimits
from aioadept.sim.controller import Controller
from aioadept.vplus import errors as E
from aioadept.vplus.locations import PrecisionPoint, Transform, compose, trans

__all__ = [
    "INRANGE_BITS", "VPLUS_ERRORS", "Location", "MotionGen", "RobotDevice", "RobotErrorSpec", "VPlusRobotError",
    "inrange_reasons",
]

TaskId = Hashable
Location = Union[Transform, PrecisionPoint]
MotionGen = Generator[float, None, None]


@dataclass(frozen=True, slots=True)
class RobotErrorSpec:
    """One V+ error: its code (negative) and the message text the controller prints (``*...*``)."""

    code: int
    text: str
    confirmed: bool = False
    """True only where a V+ manual or controller output confirmed the number."""


VPLUS_ERRORS: dict[str, RobotErrorSpec] = {
    # The robot's errors, keyed by what went wrong. Numbers come from the emulator's one code table
    # (aioadept.vplus.errors), which reuses aioadept.protocol.ErrorCode where the meaning is the same, so that the
    # emulated server and the Python sim answer the same code. None could be confirmed against a controller or
    # the manuals' error list (docs/vplus.md); "attached" and "config" have no entry there yet and are ours.
    "out_of_range": RobotErrorSpec(int(ErrorCode.OUT_OF_REACH), "*Location out of range*"),
    "joint_limit": RobotErrorSpec(int(ErrorCode.JOINT_LIMIT), "*Joint limit*"),
    "config": RobotErrorSpec(int(ErrorCode.OUT_OF_REACH), "*Cannot reach configuration*"),
    "illegal_value": RobotErrorSpec(E.ILLEGAL_VALUE, "*Illegal value*"),
    "not_attached": RobotErrorSpec(E.ROBOT_NOT_ATTACHED, "*Robot not attached to this program*"),
    "attached": RobotErrorSpec(-602, "*Robot already attached to program*"),
}


class VPlusRobotError(E.VPlusError):
    """A V+ robot error in a program (location out of range, joint limit, robot not attached, ...).

    ``code`` is the V+ error code (see :data:`VPLUS_ERRORS`), ``message`` the text. It is a
    :class:`aioadept.vplus.errors.VPlusError`, so the interpreter treats it as any V+ program error of the task
    that executed the instruction (``ERROR()``, ``$ERROR()``, REACTE).
    """

    def __init__(self, code: int, message: str) -> None:
        super().__init__(code, message)

    @classmethod
    def of(cls, key: str, detail: str | None = None) -> VPlusRobotError:
        err = VPLUS_ERRORS[key]
        return cls(err.code, err.text if not detail else f"{err.text} {detail}")


INRANGE_BITS: dict[str, int] = {
    # INRANGE's result: 0 when the location can be reached; otherwise the sum of these reason bits. Joint n's
    # limit stop is bit n (value 2**(n-1)). The positions of the other bits are UNCONFIRMED (from memory of the
    # V+ Language Reference Guide, not checked against a copy of it): keep them in this one table.
    "too_close": 0x1000,
    "too_far": 0x2000,
    "config": 0x4000,
}


def inrange_reasons(code: int) -> list[str]:
    """The reasons an INRANGE result encodes, e.g. ``["joint 3 limit", "too_far"]`` (empty for 0)."""
    out = [f"joint {j + 1} limit" for j in range(12) if code & (1 << j)]
    out += [name for name, bit in INRANGE_BITS.items() if code & bit]
    return out


CONFIG_WORDS: dict[str, dict] = {
    # V+ configuration instructions -> Controller.request_config. RIGHTY is the configuration of the home pose (wrist
    # centre in front of the J1 axis) and LEFTY the arm reaching over backwards: UNCONFIRMED for the Viper (the
    # manual defines LEFTY/RIGHTY by a human arm seen from above). ABOVE: the elbow above the line from shoulder to
    # wrist (as at home); FLIP: the wrist pitch (J5) negative, NOFLIP positive; SINGLE: J6 within -180..180 deg.
    "RIGHTY": {"shoulder": 1}, "LEFTY": {"shoulder": -1}, "ABOVE": {"elbow": 1}, "BELOW": {"elbow": -1},
    "NOFLIP": {"wrist": 1}, "FLIP": {"wrist": -1}, "SINGLE": {"single": True}, "MULTIPLE": {"single": False},
}


def _no_limits(dof: int) -> JointLimits:
    """Joint limits wide enough to see which real limit an IK solution breaks."""
    return JointLimits(min_deg=(-1e9,) * dof, max_deg=(1e9,) * dof)


class RobotDevice:
    """The robot of the emulated controller; see the module docstring.

    ``controller`` is the one robot model (its tool, speeds, trajectory and signals are the robot's). ``dry_run``
    is V+ DRY.RUN. The attribute :attr:`owner` is the task that has the robot attached (None: free). Waits
    (BREAK, a MOVE waiting for its turn) wake at least every ``poll_s`` seconds (one V+ trajectory cycle, 16 ms,
    by default) to notice a BRAKE from another task.
    """

    def __init__(self, controller: Controller | None = None, *, dry_run: bool = False,
                 poll_s: float = 0.016) -> None:
        if not poll_s > 0:
            raise ValueError(f"poll_s: {poll_s} must be > 0")
        self.controller = controller if controller is not None else Controller()
        self.dry_run = dry_run
        self.poll_s = poll_s
        """Longest a motion wait sleeps before it looks again (a BRAKE from another task may have ended it)."""
        self.owner: TaskId | None = None
        self._brakes = 0  # counts BRAKEs, so a motion instruction waiting for its turn notices one
        # the trajectory's plan as the last BRAKE left it: while it is still the plan, no motion was planned since
        # (the trajectory replaces its list of segments on every stop and every new motion)
        self._braked_plan: object = None

    # -- time --------------------------------------------------------------------------------------------
    @property
    def now_s(self) -> float:
        """The server time the next instruction executes at (the controller's clock)."""
        return self.controller.now_s

    @now_s.setter
    def now_s(self, t: float) -> None:
        # The trajectory must not be queried before its last change: time only moves forward.
        if t > self.controller.now_s:
            self.controller.now_s = float(t)

    # -- ownership ---------------------------------------------------------------------------------------
    def attach(self, task: TaskId) -> None:
        """V+ ``ATTACH ()``: ``task`` now owns the robot. Raises if another task has it attached."""
        if self.owner is not None and self.owner != task:
            raise VPlusRobotError.of("attached", f"(task {self.owner})")
        self.owner = task

    def detach(self, task: TaskId) -> None:
        """V+ ``DETACH ()``: release the robot if ``task`` has it (a task that does not is left alone)."""
        if self.owner == task:
            self.owner = None

    def _check_owner(self, task: TaskId) -> None:
        if self.owner != task:
            raise VPlusRobotError.of("not_attached")

    # -- speed -------------------------------------------------------------------------------------------
    def speed(self, task: TaskId, pct: float, *, always: bool = False) -> None:
        """V+ ``SPEED pct [ALWAYS]``: the next motion's program speed, or every motion's with ``always``."""
        self._check_owner(task)
        if not math.isfinite(pct) or pct <= 0:
            raise VPlusRobotError.of("illegal_value", f"SPEED {pct:g}")
        if always:
            self.controller.always_speed_pct = float(pct)
            self.controller.pending_speed_pct = None
        else:
            self.controller.pending_speed_pct = float(pct)

    @property
    def monitor_speed(self) -> float:
        """The monitor speed (%): effective speed = program speed x monitor speed / 100."""
        return self.controller.monitor_speed_pct

    @monitor_speed.setter
    def monitor_speed(self, pct: float) -> None:
        if not (math.isfinite(pct) and 0 < pct <= 100):
            raise VPlusRobotError.of("illegal_value", f"monitor speed {pct:g}")
        self.controller.monitor_speed_pct = float(pct)

    # -- where the robot is ------------------------------------------------------------------------------
    def here(self) -> Transform:
        """V+ ``HERE``: the tool's location now (with the current TOOL)."""
        return Transform.from_pose(self.controller.here_at(self.now_s))

    def here_ppoint(self) -> PrecisionPoint:
        """V+ ``HERE #p``: the joint angles now."""
        return PrecisionPoint(self.controller.joints_at(self.now_s))

    def _planned_end(self) -> Transform:
        """Where the planned motions leave the tool: the start of the next motion."""
        ctl = self.controller
        return Transform.from_pose(ctl.model.forward(ctl.trajectory.end_deg, ctl.tool))

    @property
    def in_motion(self) -> bool:
        return self.controller.trajectory.in_motion(self.now_s)

    # -- tool --------------------------------------------------------------------------------------------
    @property
    def tool(self) -> Transform:
        """V+ ``TOOL`` (the function): the current tool transformation."""
        return Transform.from_pose(self.controller.tool)

    def set_tool(self, task: TaskId, t: Transform) -> None:
        """V+ ``TOOL t``: later locations (HERE, move targets) are of the tool tip ``t`` in the flange frame."""
        self._check_owner(task)
        self.controller.tool = t.to_pose()

    # -- INRANGE -----------------------------------------------------------------------------------------
    def inrange(self, loc: Location) -> int:
        """V+ ``INRANGE(loc)``: 0 if the robot can reach ``loc`` from where its planned motions end, else
        reason bits (:data:`INRANGE_BITS`; joint n's limit is ``2**(n-1)``)."""
        ctl = self.controller
        limits = ctl.joint_limits
        if isinstance(loc, PrecisionPoint):
            return _limit_bits(limits, loc.joints_deg)
        pose = loc.to_pose()
        seed = ctl.trajectory.end_deg
        try:
            ctl.model.inverse(pose, seed, ctl.tool, limits=limits)
            return 0
        except RobotError as exc:
            if exc.code != ErrorCode.JOINT_LIMIT:
                return self._reach_bits(pose)
        try:
            joints = ctl.model.inverse(pose, seed, ctl.tool, limits=_no_limits(ctl.model.dof))
        except RobotError:
            return self._reach_bits(pose)
        return _limit_bits(limits, joints) or INRANGE_BITS["config"]

    def _reach_bits(self, pose: Pose) -> int:
        """No configuration reaches ``pose``: too far or too close if the model says so (a Viper's wrist centre, a
        SCARA's flange outside the annulus its arm sweeps), else the configuration (or, on a SCARA, the
        orientation) is the reason."""
        ctl = self.controller
        flange = Transform.from_pose(pose).matrix
        if ctl.tool != Pose():
            flange = flange @ inverse_transform(ctl.tool.to_matrix())
        return INRANGE_BITS[ctl.model.reach_reason(flange) or "config"]

    # -- motion ------------------------------------------------------------------------------------------
    def move(self, task: TaskId, target: Location, *, straight: bool = False) -> MotionGen:
        """V+ ``MOVE`` (``MOVES`` with ``straight``: a straight line in Cartesian space, checked along its whole
        length before it starts, :meth:`aioadept.sim.controller.Controller.move_line`).

        Returns when the motion has started (forward processing, one motion deep). Raises
        :class:`VPlusRobotError` before anything moves for an unreachable target or a joint limit.
        """
        self._check_owner(task)
        ctl = self.controller
        if isinstance(target, PrecisionPoint):
            ctl.take_config()       # a precision point's joints are its configuration: a request is moot
        if self.dry_run:
            self._check_target(target)
            ctl.take_speed_pct()
            ctl.take_duration_s()
            ctl.take_config()
            if straight:
                try:
                    ctl.plan_line(self._line_target(target))
                except RobotError as exc:
                    raise _translate(exc) from exc
            return
        epoch = self._brakes
        try:
            if isinstance(target, PrecisionPoint) and not ctl.model.dof <= len(target.joints_deg) <= 6:
                ctl.take_speed_pct()
                raise VPlusRobotError.of("illegal_value", f"precision point has {len(target.joints_deg)} joints")
            if straight:
                gen = ctl.move_line(self._line_target(target))
            elif isinstance(target, PrecisionPoint):
                gen = ctl.move_joints(target.joints_deg)
            else:
                gen = ctl.move_pose(target.to_pose())
            # Drive the controller's generator ourselves so that a BRAKE while it waits drops it unstarted, and
            # look at least every poll_s, so that the drop happens when the brake comes, not when the wait ends.
            wake = next(gen, None)
            while wake is not None:
                yield min(wake, self.now_s + self.poll_s)
                if self._brakes != epoch:
                    gen.close()
                    return
                if self.now_s >= wake:
                    wake = next(gen, None)
        except RobotError as exc:
            raise _translate(exc) from exc

    def movet(self, task: TaskId, target: Location, hand: float, *, straight: bool = False) -> MotionGen:
        """V+ ``MOVET loc, hand`` (``MOVEST`` with ``straight``): the motion of :meth:`move`, and the hand opens
        (``hand`` non-zero) or closes (zero) as that motion starts, as ``OPEN``/``CLOSE`` before a ``MOVE``
        (pneumatic hand; UNCONFIRMED which values open it, docs/vplus.md). A motion refused leaves the hand as it
        was: no deferred action is left over for a later motion."""
        self._check_owner(task)
        if not math.isfinite(hand):
            raise VPlusRobotError.of("illegal_value", "MOVET hand opening")
        io = self.controller.io
        io.defer_hand("open" if hand != 0 else "close")
        try:
            yield from self.move(task, target, straight=straight)
        except BaseException:
            io.pending_hand = None
            raise

    def set_duration(self, task: TaskId, seconds: float, *, always: bool = False) -> None:
        """V+ ``DURATION s [ALWAYS]``: the least time of the next (every) motion
        (:meth:`aioadept.sim.controller.Controller.set_duration`). Any task may set it while no other task has the
        robot attached (the manual's DURATION page)."""
        if self.owner is not None and self.owner != task:
            raise VPlusRobotError.of("attached", f"(task {self.owner})")
        try:
            self.controller.set_duration(seconds, always=always)
        except ValueError:
            raise VPlusRobotError.of("illegal_value", f"DURATION {seconds:g}") from None

    def request_config(self, task: TaskId, word: str) -> None:
        """V+ ``LEFTY``, ``RIGHTY``, ``ABOVE``, ``BELOW``, ``FLIP``, ``NOFLIP``, ``SINGLE``, ``MULTIPLE``: the
        configuration the next motion to a transformation ends in (:data:`CONFIG_WORDS`)."""
        self._check_owner(task)
        self.controller.request_config(**CONFIG_WORDS[word])

    def _line_target(self, target: Location) -> Pose:
        """The tool pose a straight line goes to: a transformation as it is, a precision point through the forward
        kinematics (with the current TOOL)."""
        if isinstance(target, PrecisionPoint):
            return self.controller.model.forward(target.joints_deg, self.controller.tool)
        return target.to_pose()

    def moves(self, task: TaskId, target: Location) -> MotionGen:
        """V+ ``MOVES``: as :meth:`move` with ``straight=True``."""
        yield from self.move(task, target, straight=True)

    def appro(self, task: TaskId, loc: Transform, dist_mm: float, *, straight: bool = False) -> MotionGen:
        """V+ ``APPRO loc, dist``: to ``dist`` mm from ``loc`` back along its tool Z axis (``loc:TRANS(0,0,-dist)``)."""
        if not math.isfinite(dist_mm):
            raise VPlusRobotError.of("illegal_value", "APPRO distance")
        yield from self.move(task, compose(loc, trans(0.0, 0.0, -dist_mm)), straight=straight)

    def depart(self, task: TaskId, dist_mm: float, *, straight: bool = False) -> MotionGen:
        """V+ ``DEPART dist``: ``dist`` mm back along the tool Z axis from where the planned motions end."""
        self._check_owner(task)
        if not math.isfinite(dist_mm):
            raise VPlusRobotError.of("illegal_value", "DEPART distance")
        yield from self.move(task, compose(self._planned_end(), trans(0.0, 0.0, -dist_mm)), straight=straight)

    def break_(self) -> MotionGen:
        """V+ ``BREAK``: resumed when every planned motion has completed and the arm is at rest."""
        # A BRAKE from another task ends the motion early: ask the controller again at least every poll_s rather
        # than sleeping until the rest time it gave before the brake.
        while True:
            gen = self.controller.wait_rest()
            wake = next(gen, None)
            gen.close()
            if wake is None:
                return
            yield min(wake, self.now_s + self.poll_s)

    def brake(self, now_s: float | None = None) -> float:
        """V+ ``BRAKE`` (any task): decelerate to rest now (at ``now_s`` if given) and drop every planned motion,
        including a motion instruction waiting for its turn. Returns the time the arm will be at rest."""
        if now_s is not None:
            self.now_s = now_s
        self._brakes += 1
        self.controller.io.pending_hand = None  # a deferred OPEN/CLOSE does not act on the motion after a stop
        traj = self.controller.trajectory
        rest = traj.stop(self.now_s)
        self._braked_plan = traj._segments
        return rest

    @property
    def braked(self) -> bool:
        """The last motion was ended by a BRAKE and none was planned since (V+ STATE(2) 5 and 6)."""
        return self._braked_plan is not None and self.controller.trajectory._segments is self._braked_plan

    def delay(self, task: TaskId, seconds: float) -> MotionGen:
        """V+ ``DELAY s``: the arm holds still for ``s`` seconds (see the module docstring for the difference)."""
        self._check_owner(task)
        if not math.isfinite(seconds) or seconds < 0:
            raise VPlusRobotError.of("illegal_value", f"DELAY {seconds:g}")
        yield from self.break_()
        traj = self.controller.trajectory
        hold = 0.0 if traj.instant else seconds / traj.time_scale
        if hold > 0:
            yield self.now_s + hold

    def hand(self, task: TaskId, action: str, *, immediate: bool) -> MotionGen:
        """V+ ``OPEN``/``CLOSE``/``RELAX`` (``action`` open, close, relax) and, with ``immediate``, ``OPENI``/
        ``CLOSEI``/``RELAXI``, on the controller's hand (:mod:`aioadept.sim.io`).

        The deferred forms return at once and act as the next motion starts. The immediate forms wait until the
        arm is at rest (as BREAK does), switch the valves, and hold the program for ``HAND.TIME``."""
        self._check_owner(task)
        io = self.controller.io
        if not immediate:
            io.defer_hand(action)
            return
        yield from self.break_()
        io.hand_now(action, self.now_s)
        hold = io.hand_hold_s()
        if hold > 0:
            yield self.now_s + hold

    def _check_target(self, target: Location) -> None:
        code = self.inrange(target)
        if code:
            bits = inrange_reasons(code)
            key = "joint_limit" if any(b.startswith("joint") for b in bits) else "out_of_range"
            raise VPlusRobotError.of(key, "(" + ", ".join(bits) + ")")


def _limit_bits(limits: JointLimits, joints_deg: tuple[float, ...] | list[float]) -> int:
    code = 0
    for j in limits.violations(joints_deg):
        code |= 1 << j
    return code


def _translate(exc: RobotError) -> VPlusRobotError:
    if exc.code == ErrorCode.JOINT_LIMIT:
        return VPlusRobotError(VPLUS_ERRORS["joint_limit"].code, f"{VPLUS_ERRORS['joint_limit'].text} {exc.message}")
    if exc.code == ErrorCode.OUT_OF_REACH:
        text = VPLUS_ERRORS["out_of_range"].text
        if exc.message.startswith(("line ", "configuration")):  # where along a line it left the workspace; FLIP+MOVES
            text = f"{text} {exc.message}"
        return VPlusRobotError(VPLUS_ERRORS["out_of_range"].code, text)
    return VPlusRobotError(int(exc.code), exc.message)
