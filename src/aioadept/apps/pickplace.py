"""Vision-guided pick and place (``aioadept pickplace``): the cell's second application, composed of coroutines as
the paper's ``ufloop`` is.

One cycle per part: wait for the feeder's part-present input, ask the locator where the part is, ``appros`` above
it, open the hand (only when it is not open already: the previous release left it open), descend on a straight
line, close, read the gripper's closed-fully input, ``departs``, ``appros`` above the next pallet slot, descend,
release, ``departs``. The locator is anything with ``async locate() -> LocateAnswer`` (:class:`Locator`): the bus
locator (:class:`BusLocator`, a ``LocateRequest`` to the vision node) is the app's; tests of the motion sequence
may plug in another.

Safety rule (as :mod:`aioadept.apps.focus`): every parameter and every pallet slot is checked before any motion;
a part the locator puts outside the workspace, a failed locate request, or no part on the feeder ends the run with
a :class:`PickPlaceError` before the cycle's first motion. "Closed on nothing" (the closed-fully switch on after
``close_hand``) opens the hand, backs off, locates again and retries once, then stops with an error. After a
cancellation (Ctrl-C, SIGHUP), a stop, a lost connection or an ack timeout, no motion is started.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from aioadept.bus.located import LOCATE_REQUEST, LocatedPart, parts_from_attributes
from aioadept.commands import (SPEED_MAX, SPEED_MIN, Appros, CloseHand, Departs, MoveToS, OpenHand, SetSpeed, Sig,
                               WaitSig)
from aioadept.cell.schema import Range, check_ranges, ranged
from aioadept.errors import AdeptError, CommandError, PickPlaceError
from aioadept.geometry import Pose
from aioadept.protocol.codes import ErrorCode
from aioadept.world import Feeder, Pallet

log = logging.getLogger(__name__)


_SPEED = Range(SPEED_MIN, SPEED_MAX, integer=True, unit="%")
MOTION_SKILLS = frozenset({"appros", "appro", "departs", "depart", "move_to_s", "move_to", "move_rel_tool_s"})
HAND_SKILLS = frozenset({"open_hand", "close_hand"})


@dataclass(frozen=True, slots=True)
class PickPlaceParams:
    """The cell file's ``[pickplace]`` table (and ``--parts``/``--speed``...): every field range-checked on
    construction (ValueError naming it)."""

    parts: int = ranged(6, Range(1, 10_000, integer=True))
    """Parts to pick and place (each to the next pallet slot)."""
    speed: int = ranged(50, _SPEED)
    """Program speed of every motion (% of the straight-line 100 %)."""
    part_timeout_s: float = ranged(10.0, Range(0.0, 3600.0, lo_open=True, unit="s"))
    """Wait at most this long for the part-present input; then stop with an error (no motion)."""
    locate_timeout_s: float = ranged(5.0, Range(0.0, 600.0, lo_open=True, unit="s"))
    approach_mm: float = ranged(60.0, Range(5.0, 300.0, unit="mm"))
    """``appros``/``departs`` distance above the part and the slot."""
    grip_depth_mm: float = ranged(10.0, Range(0.0, 200.0, unit="mm"))
    """How far below the part's top face the tool centre closes."""
    part_sensor: int = ranged(1002, Range(1001, 1512, integer=True))
    """The feeder's part-present input (the world's feeder sensor, when the cell has a world)."""
    closed_switch: int = ranged(1001, Range(1001, 1512, integer=True))
    """The gripper's closed-fully input: on after ``close_hand`` means it closed on nothing."""
    retries: int = ranged(1, Range(0, 5, integer=True))
    """Grips retried after "closed on nothing" before the run stops."""
    min_radius_mm: float = ranged(250.0, Range(0.0, 2000.0, unit="mm"))
    max_radius_mm: float = ranged(800.0, Range(0.0, 2000.0, lo_open=True, unit="mm"))
    """The workspace: a target's distance from the base axis must lie in [min_radius_mm, max_radius_mm] ..."""
    min_z_mm: float = ranged(-500.0, Range(-2000.0, 2000.0, unit="mm"))
    max_z_mm: float = ranged(1000.0, Range(-2000.0, 2000.0, unit="mm"))
    """... and its tool-centre height in [min_z_mm, max_z_mm]. A target outside is refused before any motion."""
    first_slot: int = ranged(0, Range(0, 10_000, integer=True))
    """The pallet slot the first part goes to."""

    def __post_init__(self) -> None:
        check_ranges(self)
        if self.min_radius_mm >= self.max_radius_mm:
            raise ValueError(f"min_radius_mm = {self.min_radius_mm:g}: expected less than max_radius_mm "
                             f"({self.max_radius_mm:g})")
        if self.min_z_mm >= self.max_z_mm:
            raise ValueError(f"min_z_mm = {self.min_z_mm:g}: expected less than max_z_mm ({self.max_z_mm:g})")


# ------------------------------------------------------------------------------------------------- the locator
@dataclass(frozen=True, slots=True)
class LocateAnswer:
    parts: tuple[LocatedPart, ...]
    processing_ms: float
    """The request's time: from writing it to its answer (what the cycle spends on it)."""


class Locator(Protocol):
    """Where the parts are now (:class:`BusLocator`; tests may plug in another)."""

    async def locate(self) -> LocateAnswer: ...


class Robot(Protocol):
    async def cmdexec(self, *commands: Any, **kw: Any) -> Any: ...


class BusLocator:
    """A ``LocateRequest`` through a :class:`~aioadept.bus.Communicator` to the vision node's part locator; the
    answer's attributes are the flat ``parts`` / ``part.<i>.<field>`` form (docs/pickplace.md). Raises
    :class:`PickPlaceError` for an error answer, no answer in time or an answer that is not a list of parts."""

    def __init__(self, comm: Any, *, timeout_s: float) -> None:
        self.comm = comm
        self.timeout_s = timeout_s

    async def locate(self) -> LocateAnswer:
        t0 = time.monotonic()
        try:
            resp = await self.comm.request(LOCATE_REQUEST, {}, timeout_s=self.timeout_s)
        except TimeoutError as exc:
            raise PickPlaceError(f"locate: no answer from the vision node within {self.timeout_s:g} s") from exc
        except AdeptError as exc:
            raise PickPlaceError(f"locate: {exc}") from exc
        ms = (time.monotonic() - t0) * 1000.0
        return LocateAnswer(parts_of(dict(resp.attributes)), ms)


def parts_of(attrs: dict[str, Any]) -> tuple[LocatedPart, ...]:
    """The parts of a locate answer's attributes (:func:`aioadept.bus.located.parts_from_attributes`);
    :class:`PickPlaceError` for an error answer or a bad one."""
    if attrs.get("error"):
        raise PickPlaceError(f"locate: the vision node answered: {attrs['error']}")
    try:
        return parts_from_attributes(attrs)
    except AdeptError as exc:
        raise PickPlaceError(f"{exc}; no motion") from None


# ------------------------------------------------------------------------------------------------- the geometry
def tool_down(x_mm: float, y_mm: float, z_mm: float, heading_deg: float) -> Pose:
    """The tool pointing down at (x, y, z), its x axis along ``heading_deg`` about the base z axis (Adept Z-Y-Z at
    pitch 180: the tool's x heads 180 - roll, so roll = 180 - heading), roll folded into (-180, 180]."""
    roll = (180.0 - heading_deg + 180.0) % 360.0 - 180.0
    return Pose(x_mm, y_mm, z_mm, 0.0, 180.0, roll if roll != -180.0 else 180.0)


def fold_heading(heading_deg: float, ref_deg: float = 0.0) -> float:
    """``heading_deg`` turned by a multiple of 180 deg to lie within 90 deg of ``ref_deg`` (a two-finger grip of a
    box or cylinder is the same after a half turn; the shorter turn of joint 6 wins)."""
    return ref_deg + ((heading_deg - ref_deg + 90.0) % 180.0) - 90.0


def check_workspace(what: str, pose: Pose, p: PickPlaceParams) -> None:
    """PickPlaceError unless ``pose``'s tool centre lies in the workspace (:class:`PickPlaceParams`)."""
    r = math.hypot(pose.x, pose.y)
    if not (p.min_radius_mm <= r <= p.max_radius_mm and p.min_z_mm <= pose.z <= p.max_z_mm):
        raise PickPlaceError(
            f"{what} at x={pose.x:.1f} y={pose.y:.1f} z={pose.z:.1f} mm is outside the workspace (radius "
            f"{p.min_radius_mm:g}..{p.max_radius_mm:g} mm from the base axis, z {p.min_z_mm:g}..{p.max_z_mm:g} mm): "
            f"refused before any motion")


def on_feeder(parts: Sequence[LocatedPart], feeder: Feeder | None) -> LocatedPart | None:
    """The located part nearest the feeder's centre, among those inside it (the first part without a feeder)."""
    if feeder is None:
        return parts[0] if parts else None
    inside = [q for q in parts if feeder.contains(q.x_mm, q.y_mm)]
    return min(inside, key=lambda q: math.hypot(q.x_mm - feeder.x_mm, q.y_mm - feeder.y_mm), default=None)


# ------------------------------------------------------------------------------------------------- the result
@dataclass(slots=True)
class Cycle:
    """One part's cycle: wall-clock times (client, s) and what the acks said."""

    index: int
    slot: int
    t_start_s: float = 0.0
    t_end_s: float = 0.0
    located: LocatedPart | None = None
    locate_ms: float = 0.0
    motion_s: float = 0.0
    """The commanded motions' durations on the server's clock (each motion's start to its break's done)."""
    hand_s: float = 0.0
    """The hand's HAND.TIME waits (close and release; an open before a first or retried grip too)."""
    attempts: int = 0
    placed: bool = False
    steps: list[tuple[str, float, float]] = field(default_factory=list)
    """(phase, start s, end s) on the client's monotonic clock (asyncio's), for the Gantt chart."""

    @property
    def cycle_ms(self) -> float:
        return (self.t_end_s - self.t_start_s) * 1000.0

    @property
    def floor_ms(self) -> float:
        return (self.motion_s + self.hand_s) * 1000.0 + self.locate_ms


@dataclass(slots=True)
class PickPlaceResult:
    cycles: list[Cycle] = field(default_factory=list)

    @property
    def parts_placed(self) -> int:
        return sum(c.placed for c in self.cycles)


def _durations(res: Any, cycle: Cycle) -> None:
    """Add the server-clock durations of an ExecResult's motions (motion ack start .. following break's done) and
    hand waits to ``cycle``."""
    msgs = list(res.messages)
    for m in msgs:  # the Gantt chart's rows: each message from its write to its ack (the loop's clock, monotonic)
        if m.skill not in ("set_speed", "break"):
            end = m.t_recv_s
            nxt = msgs[msgs.index(m) + 1] if msgs.index(m) + 1 < len(msgs) else None
            if nxt is not None and nxt.skill == "break":
                end = nxt.t_recv_s  # a motion ends when its break is acked
            cycle.steps.append((m.skill, m.t_send_s, end))
    for i, m in enumerate(msgs):
        if m.skill in MOTION_SKILLS:
            end = m.ack.t_done_s
            if i + 1 < len(msgs) and msgs[i + 1].skill == "break":
                end = msgs[i + 1].ack.t_done_s
            cycle.motion_s += max(0.0, end - m.ack.t_start_s)
        elif m.skill in HAND_SKILLS:
            cycle.hand_s += max(0.0, m.ack.t_done_s - m.ack.t_start_s)


# ------------------------------------------------------------------------------------------------- the coroutines
async def wait_part(rc: Robot, p: PickPlaceParams) -> None:
    """Wait for the part-present input; PickPlaceError (no motion) when it stays off ``part_timeout_s``."""
    try:
        await rc.cmdexec(WaitSig(p.part_sensor, p.part_timeout_s), timeout_s=p.part_timeout_s + 10.0)
    except CommandError as exc:
        if exc.code == ErrorCode.SIGNAL_TIMEOUT:
            raise PickPlaceError(f"no part on the feeder: input {p.part_sensor} (part present) stayed off "
                                 f"{p.part_timeout_s:g} s; no motion") from None
        raise


async def locate_part(locator: Locator, feeder: Feeder | None) -> tuple[LocatedPart, float]:
    """Ask the locator; the part on the feeder and the request's time (ms). PickPlaceError if none is there."""
    try:
        answer = await locator.locate()
    except PickPlaceError:
        raise
    except (AdeptError, OSError) as exc:
        raise PickPlaceError(f"locate failed: {exc}; no motion") from exc
    part = on_feeder(answer.parts, feeder)
    if part is None:
        where = "" if feeder is None else f" in the feeder at x={feeder.x_mm:g} y={feeder.y_mm:g} mm"
        raise PickPlaceError(f"locate: the locator found no part{where} ({len(answer.parts)} elsewhere); no motion")
    return part, answer.processing_ms


async def pick(rc: Robot, part: LocatedPart, p: PickPlaceParams, cycle: Cycle, *, hand_open: bool) -> Pose:
    """``appros`` above the part, open (unless ``hand_open``), descend, close; returns the grip pose. Raises
    PickPlaceError when the gripper closed on nothing (the hand is then opened and backed off)."""
    heading = fold_heading(part.yaw_deg)
    grip = tool_down(part.x_mm, part.y_mm, part.z_mm - p.grip_depth_mm, heading)
    check_workspace("the part's grip pose", grip, p)
    above = tool_down(part.x_mm, part.y_mm, grip.z + p.approach_mm, heading)
    check_workspace("the pose above the part", above, p)
    cmds: list[Any] = [SetSpeed(p.speed), Appros(grip, p.approach_mm)]
    if not hand_open:
        cmds.append(OpenHand())
    cmds += [SetSpeed(p.speed), MoveToS(grip), CloseHand(), Sig(p.closed_switch)]
    res = await rc.cmdexec(*cmds)
    _durations(res, cycle)
    if Sig.states(res.messages[-1].ack)[0]:
        res = await rc.cmdexec(OpenHand(), SetSpeed(p.speed), Departs(p.approach_mm))
        _durations(res, cycle)
        raise PickPlaceError(f"the gripper closed on nothing at x={grip.x:.1f} y={grip.y:.1f} mm (input "
                             f"{p.closed_switch} on): the part is not where the locator said", moved=True)
    return grip


async def place(rc: Robot, slot: tuple[float, float, float], grip: Pose, p: PickPlaceParams, cycle: Cycle,
                heading_deg: float) -> None:
    """``departs`` with the part, ``appros`` above the slot turned to its heading, descend, release, ``departs``."""
    sx, sy, sh = slot
    # The part keeps its pose in the tool: turn the tool by the turn that brings the part's heading to the slot's.
    tool_heading = sh - (heading_deg - fold_heading(heading_deg))
    target = tool_down(sx, sy, grip.z, tool_heading)
    res = await rc.cmdexec(SetSpeed(p.speed), Departs(p.approach_mm), SetSpeed(p.speed), Appros(target, p.approach_mm),
                           SetSpeed(p.speed), MoveToS(target), OpenHand(), SetSpeed(p.speed), Departs(p.approach_mm))
    _durations(res, cycle)


def slot_targets(pallet: Pallet, p: PickPlaceParams, grip_z_mm: float) -> list[tuple[float, float, float]]:
    """The slots the run fills, checked against the pallet and the workspace before any motion."""
    last = p.first_slot + p.parts - 1
    if last >= pallet.slots:
        raise PickPlaceError(f"{p.parts} parts from slot {p.first_slot} need {last + 1} pallet slots; the pallet has "
                             f"{pallet.slots} ({pallet.rows} x {pallet.cols}); nothing was moved")
    out = []
    for i in range(p.first_slot, last + 1):
        x, y, h = pallet.slot_xy(i)
        for what, z in (("above", grip_z_mm + p.approach_mm), ("", grip_z_mm)):
            check_workspace(f"pallet slot {i}{' ' + what if what else ''}", tool_down(x, y, z, h), p)
        out.append((x, y, h))
    return out


async def pickplace(rc: Robot, locator: Locator, p: PickPlaceParams, *, pallet: Pallet, feeder: Feeder | None,
                    table_z_mm: float, recorder: Any = None,
                    on_cycle: Callable[[Cycle], Any] | None = None) -> PickPlaceResult:
    """Pick ``p.parts`` parts from the feeder and place each in the next pallet slot; see the module docstring.

    ``table_z_mm``: the height of the pallet's surface (the part is set down with its bottom where it was picked
    from, so the feeder and the pallet lie on the same plane). ``on_cycle(cycle)`` is called after each placed part
    (the caller's world check). Raises :class:`PickPlaceError` with ``moved`` False for every fault found before a
    cycle's first motion; the partial result is on the exception's ``result``.
    """
    result = PickPlaceResult()
    # Every slot the run will use, checked before the first motion (with the grip height the feeder's parts will
    # have, when known; the slot check is repeated per part with the located height).
    grip_z = table_z_mm + 1.0
    slots = slot_targets(pallet, p, grip_z)
    hand_open = False
    try:
        for k in range(p.parts):
            cycle = Cycle(k, p.first_slot + k, time.monotonic())
            result.cycles.append(cycle)
            if recorder is not None:
                recorder.mark("part", k)
            t0 = time.monotonic()
            await wait_part(rc, p)
            cycle.steps.append(("wait part", t0, time.monotonic()))
            for attempt in range(p.retries + 1):
                cycle.attempts = attempt + 1
                t0 = time.monotonic()
                part, ms = await locate_part(locator, feeder)
                cycle.steps.append(("locate", t0, time.monotonic()))
                cycle.located, cycle.locate_ms = part, cycle.locate_ms + ms
                x, y, h = slots[k]
                for what, z in (("", 0.0), (" above", p.approach_mm)):  # where this part will be set down
                    check_workspace(f"pallet slot {cycle.slot}{what}",
                                    tool_down(x, y, part.z_mm - p.grip_depth_mm + z, h), p)
                try:
                    grip = await pick(rc, part, p, cycle, hand_open=hand_open)
                    hand_open = False
                    break
                except PickPlaceError as exc:
                    if not exc.moved:
                        raise
                    hand_open = True
                    if attempt == p.retries:
                        raise PickPlaceError(f"part {k + 1}: {exc} ({attempt + 1} tries); stopped",
                                             moved=True, part=k) from None
                    log.warning("part %d: %s; retrying", k + 1, exc)
            else:  # pragma: no cover (the loop breaks or raises)
                raise AssertionError
            await place(rc, slots[k], grip, p, cycle, part.yaw_deg)
            hand_open = True
            cycle.placed = True
            cycle.t_end_s = time.monotonic()
            # a line per part, as the focus app's per step: a long run shows where it is
            log.info("part %d of %d placed: slot %d, %.0f ms", k + 1, p.parts, cycle.slot, cycle.cycle_ms)
            if on_cycle is not None:
                on_cycle(cycle)
    except BaseException as exc:  # the partial result goes with the error (a cancellation's too)
        if isinstance(exc, PickPlaceError):
            exc.part = len(result.cycles) - 1
        with contextlib.suppress(AttributeError):
            exc.result = result  # type: ignore[attr-defined]
        raise
    return result
