"""Digital I/O and the hand of the simulated controller: the one model both backends drive.

Pure, like :mod:`aioadept.sim.controller` (time is passed in, nothing sleeps). The controller owns one
:class:`DigitalIO` (``ctl.io``); the Python sim's skills (:mod:`aioadept.sim.skills`) and the V+ emulator's
``SIGNAL``, ``SIG()``, ``BITS``, ``OPEN``/``OPENI``, ``CLOSE``/``CLOSEI``, ``RELAX``/``RELAXI`` and
``PARAMETER HAND.TIME`` (:mod:`aioadept.vplus.builtins`) all call it, so the two backends cannot disagree.

V+ signal numbering (V+ Language User's Guide, "Digital I/O"; docs/vplus.md):

- ``1..512``: digital outputs (``SIGNAL n`` turns one on, ``SIGNAL -n`` off);
- ``1001..1512``: digital inputs (read only for a program: ``SIGNAL 1001`` is an error);
- ``2001..2512``: internal soft signals (set and read by programs, no hardware).

Every change of a signal is kept with its server time in :attr:`DigitalIO.changes` (with a running sequence
number, so that a state stream can send each change once: :meth:`DigitalIO.changes_since`).

The hand is a pneumatic gripper on two valve outputs (:class:`HandConfig`): the open valve on and the close valve
off drives it open, the reverse closed, both off relaxes it (no force; it stays where it is). It takes
``close_time_s`` to travel fully. Its closed-fully switch (an input, ``closed_switch``) is on only when the
fingers are fully closed, i.e. closed on nothing: closing on a part (:attr:`Hand.part`, set by a test or by the
sim's world, :mod:`aioadept.world`) stops the fingers short, and the switch stays off. A missed pick is
therefore visible as ``SIG(closed_switch)`` after ``CLOSEI``.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from enum import Enum

from aioadept.errors import RobotError
from aioadept.protocol import ErrorCode

OUTPUTS = range(1, 513)
"""Digital output signal numbers (V+: 1..512; a controller has only those its I/O boards provide)."""
INPUTS = range(1001, 1513)
"""Digital input signal numbers (V+: 1001..1512)."""
SOFT = range(2001, 2513)
"""Internal (soft) signal numbers (V+: 2001..2512)."""

HAND_TIME_S = 0.05
"""Default of V+ ``PARAMETER HAND.TIME`` (s): how long ``OPENI``/``CLOSEI``/``RELAXI`` hold the program after
switching the valves. UNCONFIRMED default (docs/vplus.md); the shipped rsconfig.V2 sets the same value."""
MAX_HAND_TIME_S = 60.0
"""Largest HAND.TIME accepted (s): beyond it the value is a typo that would hold the executor for minutes."""

MAX_CHANGES = 4096
"""Changes kept in :attr:`DigitalIO.changes` (older ones are dropped; the state stream reads them at >= 10 Hz)."""


class SignalKind(str, Enum):
    OUTPUT = "output"
    INPUT = "input"
    SOFT = "soft"


def signal_kind(n: int) -> SignalKind | None:
    """The kind of signal ``abs(n)`` is, or None if no such signal exists."""
    k = abs(n)
    if k in OUTPUTS:
        return SignalKind.OUTPUT
    if k in INPUTS:
        return SignalKind.INPUT
    if k in SOFT:
        return SignalKind.SOFT
    return None


def signal_number(value: float, what: str = "signal") -> int:
    """A wire or V+ number as a signal number: an integer, not 0, of an existing signal (its sign kept).

    Raises :class:`RobotError` ``ILLEGAL_SIGNAL`` (or ``ILLEGAL_VALUE`` for a number that is not an integer)."""
    if not math.isfinite(value) or value != int(value):
        raise RobotError(ErrorCode.ILLEGAL_VALUE, f"{what} {value:.6g} is not an integer")
    n = int(value)
    if n == 0 or signal_kind(n) is None:
        raise RobotError(ErrorCode.ILLEGAL_SIGNAL, f"no {what} {abs(n)} (outputs 1-512, inputs 1001-1512, "
                                                   f"soft signals 2001-2512)")
    return n


@dataclass(frozen=True, slots=True)
class SignalChange:
    """One change of one signal: at server time ``t_s`` signal ``signal`` became ``on``."""

    seq: int
    t_s: float
    signal: int
    on: bool


@dataclass(frozen=True, slots=True)
class HandConfig:
    """Where the hand is wired (as a controller's configuration sets it) and how fast it moves.

    ``open_signal``/``close_signal``: the valve outputs (UNCONFIRMED defaults: the first two outputs);
    ``closed_switch``: the input of the closed-fully switch (None: the gripper has none);
    ``close_time_s``: full travel, open to closed or back (divided by the controller's time scale). The default
    is shorter than the default HAND.TIME, as a site sets HAND.TIME to cover its gripper's travel: when
    ``close_hand`` acks, the closed-fully switch already tells a miss from a grip."""

    open_signal: int = 1
    close_signal: int = 2
    closed_switch: int | None = 1001
    close_time_s: float = 0.04

    def __post_init__(self) -> None:
        for name in ("open_signal", "close_signal"):
            if signal_kind(getattr(self, name)) is not SignalKind.OUTPUT or getattr(self, name) < 0:
                raise ValueError(f"{name}: {getattr(self, name)} is not a digital output (1-512)")
        if self.open_signal == self.close_signal:
            raise ValueError("open_signal and close_signal must differ")
        if self.closed_switch is not None and (self.closed_switch < 0
                                               or signal_kind(self.closed_switch) is not SignalKind.INPUT):
            raise ValueError(f"closed_switch: {self.closed_switch} is not a digital input (1001-1512)")
        if not (math.isfinite(self.close_time_s) and self.close_time_s >= 0):
            raise ValueError(f"close_time_s: {self.close_time_s} must be >= 0")


class HandState(str, Enum):
    OPEN = "open"
    OPENING = "opening"
    CLOSED = "closed"
    CLOSING = "closing"
    RELAXED = "relaxed"


PART_STOP = 0.6
"""Where closing fingers stop on a part (0 = fully open, 1 = fully closed)."""


class Hand:
    """The gripper: finger position 0 (open) .. 1 (closed), driven by its two valves (see the module docstring)."""

    def __init__(self, config: HandConfig, travel_s: float) -> None:
        self.config = config
        self.travel_s = travel_s
        self.part = False
        """A part is between the fingers: closing stops on it (set by tests, later by the sim's world)."""
        self.drive: HandState = HandState.RELAXED   # OPEN, CLOSED or RELAXED: what the valves ask for
        self._pos0 = 0.0                            # position at _t0
        self._t0 = 0.0

    def goal(self) -> float | None:
        """Where the valves drive the fingers (0 open .. 1 closed; short of 1 on a part), None when relaxed."""
        if self.drive is HandState.OPEN:
            return 0.0
        if self.drive is HandState.CLOSED:
            return PART_STOP if self.part and self._pos0 <= PART_STOP else 1.0
        return None

    def position(self, t_s: float) -> float:
        goal = self.goal()
        if goal is None:
            return self._pos0
        if self.travel_s <= 0:
            return goal
        step = (t_s - self._t0) / self.travel_s
        if goal >= self._pos0:
            return min(goal, self._pos0 + step)
        return max(goal, self._pos0 - step)

    def arrival_s(self) -> float | None:
        """When the fingers reach their goal (None: relaxed, no goal)."""
        goal = self.goal()
        if goal is None:
            return None
        return self._t0 + abs(goal - self._pos0) * self.travel_s

    def set_drive(self, drive: HandState, t_s: float) -> None:
        self._pos0 = self.position(t_s)
        self._t0 = t_s
        self.drive = drive

    def state(self, t_s: float) -> HandState:
        if self.drive is HandState.RELAXED:
            return HandState.RELAXED
        arrival = self.arrival_s()
        done = arrival is None or t_s >= arrival
        if self.drive is HandState.OPEN:
            return HandState.OPEN if done else HandState.OPENING
        return HandState.CLOSED if done else HandState.CLOSING

    def closed_fully(self, t_s: float) -> bool:
        # Opening fingers leave the switch at once; relaxed ones stay where they are.
        return self.drive is not HandState.OPEN and self.position(t_s) >= 1.0

    def holding(self, t_s: float) -> bool:
        """Closed on a part (the fingers stopped short)."""
        return self.state(t_s) is HandState.CLOSED and self.position(t_s) < 1.0


@dataclass(frozen=True, slots=True)
class IoSnapshot:
    """The I/O part of a state sample: the signals that are on, by kind, and the hand's state."""

    outputs_on: tuple[int, ...] = ()
    inputs_on: tuple[int, ...] = ()
    soft_on: tuple[int, ...] = ()
    hand: str = HandState.RELAXED.value


_HAND_ACTIONS = ("open", "close", "relax")


class DigitalIO:
    """Outputs, inputs and soft signals, the hand, HAND.TIME and the change log; see the module docstring.

    ``time_scale``/``instant`` are the controller's (hand travel and HAND.TIME shrink with it, as motion does).
    :attr:`values` holds every signal that is on or was ever set (missing = off); change it only through the
    methods, which log each change.
    """

    def __init__(self, hand: HandConfig = HandConfig(), *, hand_time_s: float = HAND_TIME_S,
                 time_scale: float = 1.0, instant: bool = False) -> None:
        if not time_scale > 0:
            raise ValueError(f"time_scale: {time_scale} must be > 0")
        self.time_scale = float(time_scale)
        self.instant = instant
        self.hand_config = hand
        self.values: dict[int, bool] = {}
        self.changes: deque[SignalChange] = deque(maxlen=MAX_CHANGES)
        self._seq = 0
        self.hand_time_s = HAND_TIME_S
        self.set_hand_time(hand_time_s)
        self.hand = Hand(hand, 0.0 if instant else hand.close_time_s / self.time_scale)
        self.pending_hand: str | None = None
        """A deferred OPEN/CLOSE/RELAX waiting for the start of the next motion."""
        self._switch_at: float | None = None        # when the closed-fully switch turns on (a pending event)
        self._now = 0.0
        self.on_advance: Callable[[float], None] | None = None
        """Called whenever the I/O advances to a time (every read and write of a signal does): the controller's
        world brings the feeder's next part there (aioadept.world, ``World.step``), so that inputs it drives
        change on both backends at the same times."""
        self.on_drive: Callable[[HandState, float], None] | None = None
        """Called when the valves drive the hand another way (open, closed, relaxed), at that time, before the
        closed-fully switch is updated: the controller's world (aioadept.world) grasps or releases a part
        there and sets :attr:`Hand.part`."""

    # -- reading -------------------------------------------------------------------------------------------
    def scaled(self, time_scale: float, instant: bool) -> DigitalIO:
        """Take the controller's time scale (hand travel and HAND.TIME shrink with it, as motion does); self."""
        if not time_scale > 0:
            raise ValueError(f"time_scale: {time_scale} must be > 0")
        self.time_scale, self.instant = float(time_scale), instant
        self.hand.travel_s = 0.0 if instant else self.hand_config.close_time_s / self.time_scale
        return self

    def snapshot(self, t_s: float) -> IoSnapshot:
        """The signals that are on and the hand at ``t_s``, for the state stream."""
        self.advance(t_s)
        return IoSnapshot(self.on_signals(SignalKind.OUTPUT), self.on_signals(SignalKind.INPUT),
                          self.on_signals(SignalKind.SOFT), self.hand.state(t_s).value)

    def state(self, n: int) -> bool:
        """The state of signal ``abs(n)`` now (as of the last :meth:`advance`)."""
        return self.values.get(abs(n), False)

    def sig(self, nums: Iterable[float], t_s: float) -> bool:
        """V+ ``SIG(n, ...)``: True if every signal is in the state asked for (n > 0 on, n < 0 off).

        Raises ``ILLEGAL_SIGNAL`` for a number that is no signal (before reading any)."""
        self.advance(t_s)
        ns = [signal_number(n) for n in nums]
        return all(self.state(n) == (n > 0) for n in ns)

    def on_signals(self, kind: SignalKind) -> tuple[int, ...]:
        """The signals of one kind that are on, in order."""
        rng = {SignalKind.OUTPUT: OUTPUTS, SignalKind.INPUT: INPUTS, SignalKind.SOFT: SOFT}[kind]
        return tuple(sorted(n for n, on in self.values.items() if on and n in rng))

    def bits(self, first: float, count: float, t_s: float) -> int:
        """V+ ``BITS(first, count)``: signals first..first+count-1 as a binary number (first = bit 0)."""
        self.advance(t_s)
        n0, k = int(first), int(count)
        if not 1 <= k <= 32:
            raise RobotError(ErrorCode.ILLEGAL_VALUE, f"BITS count {count:g} outside 1..32")
        signal_number(n0)
        signal_number(n0 + k - 1)
        return sum(1 << i for i in range(k) if self.state(n0 + i))

    # -- writing -------------------------------------------------------------------------------------------
    def signal(self, nums: Iterable[float], t_s: float) -> None:
        """V+ ``SIGNAL n, ...``: outputs and soft signals on (n > 0) or off (n < 0).

        Every number is checked before any signal changes: a number that is no signal, or an input, raises
        ``ILLEGAL_SIGNAL`` and nothing changes."""
        self.advance(t_s)
        ns = [signal_number(n) for n in nums]
        for n in ns:
            if signal_kind(n) is SignalKind.INPUT:
                raise RobotError(ErrorCode.ILLEGAL_SIGNAL, f"signal {abs(n)} is an input (SIGNAL sets outputs and "
                                                           f"soft signals)")
        for n in ns:
            self._set(abs(n), n > 0, t_s)
        self._valves_changed(t_s)

    def bits_set(self, first: float, count: float, value: float, t_s: float) -> None:
        """V+ ``BITS first, count = value``: set signals first..first+count-1 to the bits of ``value``."""
        self.advance(t_s)
        n0, k, v = int(first), int(count), int(value)
        if not 1 <= k <= 32:
            raise RobotError(ErrorCode.ILLEGAL_VALUE, f"BITS count {count:g} outside 1..32")
        nums = [n0 + i if (v >> i) & 1 else -(n0 + i) for i in range(k)]
        self.signal(nums, t_s)

    def set_input(self, n: int, on: bool, t_s: float) -> None:
        """Drive an input (the test API, and later the sim's world). ``n`` must be an input (1001..1512)."""
        self.advance(t_s)
        k = signal_number(n, "input")
        if signal_kind(k) is not SignalKind.INPUT or k < 0:
            raise RobotError(ErrorCode.ILLEGAL_SIGNAL, f"signal {n} is not an input (1001-1512)")
        self._set(k, bool(on), t_s)

    def _set(self, n: int, on: bool, t_s: float) -> None:
        if self.values.get(n, False) == on:
            return  # not a change (a signal never set is off)
        self.values[n] = on
        self._seq += 1
        self.changes.append(SignalChange(self._seq, t_s, n, on))

    # -- the hand ------------------------------------------------------------------------------------------
    def set_hand_time(self, seconds: float) -> None:
        """V+ ``PARAMETER HAND.TIME = seconds``."""
        if not (math.isfinite(seconds) and 0 <= seconds <= MAX_HAND_TIME_S):
            raise RobotError(ErrorCode.ILLEGAL_VALUE, f"HAND.TIME {seconds:g} outside 0..{MAX_HAND_TIME_S:g} s")
        self.hand_time_s = float(seconds)

    def hand_hold_s(self) -> float:
        """How long an immediate hand instruction holds the program (HAND.TIME, at the time scale)."""
        return 0.0 if self.instant else self.hand_time_s / self.time_scale

    def defer_hand(self, action: str) -> None:
        """V+ ``OPEN``/``CLOSE``/``RELAX``: act at the start of the next motion (:meth:`motion_started`)."""
        if action not in _HAND_ACTIONS:
            raise ValueError(f"hand action {action!r}")
        self.pending_hand = action

    def hand_now(self, action: str, t_s: float) -> None:
        """Switch the hand valves now (the immediate forms; a deferred action still pending is dropped:
        the later instruction wins)."""
        if action not in _HAND_ACTIONS:
            raise ValueError(f"hand action {action!r}")
        self.pending_hand = None
        c = self.hand.config
        o, k = c.open_signal, c.close_signal
        nums = {"open": (-k, o), "close": (-o, k), "relax": (-o, -k)}[action]
        self.signal(nums, t_s)

    def motion_started(self, t_s: float) -> None:
        """A motion starts now: a deferred hand action acts."""
        if self.pending_hand is not None:
            self.hand_now(self.pending_hand, t_s)

    def set_part_in_hand(self, present: bool, t_s: float) -> None:
        """A part is (or is no longer) between the fingers (the test API; later the sim's world)."""
        self.advance(t_s)
        self.hand.set_drive(self.hand.drive, t_s)   # rebase the travel at t_s before its goal changes
        self.hand.part = bool(present)
        self._update_switch(t_s)

    def hand_state(self, t_s: float) -> HandState:
        return self.hand.state(t_s)

    def _valves_changed(self, t_s: float) -> None:
        c = self.hand.config
        o, k = self.state(c.open_signal), self.state(c.close_signal)
        drive = HandState.OPEN if o and not k else HandState.CLOSED if k and not o else HandState.RELAXED
        if drive is self.hand.drive:
            return
        self.hand.set_drive(drive, t_s)
        if self.on_drive is not None:
            # after set_drive (the travel so far is rebased with the old part flag), before the switch reads it
            self.on_drive(drive, t_s)
        self._update_switch(t_s)

    def _update_switch(self, t_s: float) -> None:
        sw = self.hand.config.closed_switch
        if sw is None:
            return
        fully = self.hand.closed_fully(t_s)
        self._set(sw, fully, t_s)
        self._switch_at = None
        if not fully and self.hand.drive is HandState.CLOSED:
            arrival = self.hand.arrival_s()
            if arrival is not None and self.hand.goal() == 1.0:
                self._switch_at = arrival

    # -- time ----------------------------------------------------------------------------------------------
    def advance(self, t_s: float) -> None:
        """Process what the hand does up to ``t_s`` (the closed-fully switch turns on at its own time), and what
        :attr:`on_advance` adds (the world's feeder)."""
        if t_s < self._now:
            return
        self._now = t_s
        if self.on_advance is not None:
            self.on_advance(t_s)
        if self._switch_at is not None and self._switch_at <= t_s:
            at = self._switch_at
            self._switch_at = None
            sw = self.hand.config.closed_switch
            assert sw is not None
            self._set(sw, True, at)

    def next_event_s(self) -> float | None:
        """When the I/O next changes by itself (the closed-fully switch), or None."""
        return self._switch_at

    def changes_since(self, seq: int) -> tuple[list[SignalChange], int]:
        """The changes after sequence number ``seq`` and the sequence number to ask from next time."""
        out = [c for c in self.changes if c.seq > seq]
        return out, self._seq


def check_nums(values: Sequence[float], what: str = "signal", *, skill: str = "signal") -> list[int]:
    """Signal numbers from wire arguments (see :func:`signal_number`); at least one (else an error naming
    ``skill``, the skill the client called)."""
    if not values:
        raise RobotError(ErrorCode.WRONG_ARGUMENT_COUNT, f"{skill} needs at least one signal number")
    return [signal_number(v, what) for v in values]


__all__ = [
    "HAND_TIME_S", "INPUTS", "OUTPUTS", "SOFT", "DigitalIO", "Hand", "HandConfig", "HandState", "IoSnapshot",
    "SignalChange",
    "SignalKind", "check_nums", "signal_kind", "signal_number",
]
