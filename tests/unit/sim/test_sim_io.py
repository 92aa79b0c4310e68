"""Digital I/O and the hand (aioadept.sim.io) and the Python sim's I/O skills, on the pure controller."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as hst

from aioadept.errors import RobotError
from aioadept.protocol import ErrorCode, Status
from aioadept.sim.controller import Controller
from aioadept.sim.io import DigitalIO, HandConfig, HandState, SignalKind, signal_kind

HOME = (0.0, -90.0, 180.0, 0.0, 90.0, 0.0)


def changes(io: DigitalIO) -> list[tuple[float, int, bool]]:
    return [(c.t_s, c.signal, c.on) for c in io.changes_since(0)[0]]


def test_numbering_follows_v_plus():
    assert [signal_kind(n) and signal_kind(n).value for n in (1, 512, 513, 1000, 1001, -1512, 1513, 2001, 2512,
                                                              2513, 0)] == [
        "output", "output", None, None, "input", "input", None, "soft", "soft", None, None]


def test_signal_is_all_or_nothing_and_logs_each_change():
    io = DigitalIO()
    io.signal([3, 2001], 0.5)
    for bad, code in [([4, 1001], ErrorCode.ILLEGAL_SIGNAL), ([4, 9999], ErrorCode.ILLEGAL_SIGNAL),
                      ([4, 0], ErrorCode.ILLEGAL_SIGNAL), ([4, 2.5], ErrorCode.ILLEGAL_VALUE),
                      ([4, math.nan], ErrorCode.ILLEGAL_VALUE)]:
        with pytest.raises(RobotError) as info:
            io.signal(bad, 1.0)
        assert info.value.code == code
    assert not io.state(4), "a refused SIGNAL switched an earlier number of its list"
    io.signal([3, -2001, -5], 2.0)  # 3 already on, 5 already off: no change logged for them
    assert changes(io) == [(0.5, 3, True), (0.5, 2001, True), (2.0, 2001, False)]
    assert io.sig([3, -2001, -5], 2.0) and not io.sig([3, 2001], 2.0)
    new, seq = io.changes_since(2)
    assert [(c.signal, c.on) for c in new] == [(2001, False)] and io.changes_since(seq)[0] == []


def test_inputs_only_through_the_test_api():
    io = DigitalIO()
    io.set_input(1005, True, 1.0)
    assert io.sig([1005], 1.0)
    for n in (5, 2001, 3000):
        with pytest.raises(RobotError) as info:
            io.set_input(n, True, 1.0)
        assert info.value.code == ErrorCode.ILLEGAL_SIGNAL


def test_bits_read_and_write():
    io = DigitalIO()
    io.bits_set(9, 4, 0b1010, 0.0)
    assert io.bits(9, 4, 0.0) == 0b1010 and io.state(10) and io.state(12) and not io.state(9)


def test_hand_closes_in_its_time_and_the_switch_says_closed_on_nothing():
    io = DigitalIO(HandConfig(close_time_s=0.4)).scaled(2.0, False)   # time scale 2: travel 0.2 s
    io.hand_now("close", 1.0)
    assert io.hand_state(1.1) is HandState.CLOSING and not io.sig([1001], 1.1)
    assert io.hand_state(1.2) is HandState.CLOSED and io.sig([1001], 1.2)
    assert (1.2, 1001, True) in changes(io), "the switch change carries the time it happened, not when it was read"
    io.hand_now("open", 2.0)
    assert not io.sig([1001], 2.0), "opening fingers leave the switch at once"
    assert io.hand_state(2.2) is HandState.OPEN
    io.hand_now("relax", 3.0)
    assert io.hand_state(3.0) is HandState.RELAXED and not io.state(1) and not io.state(2)


def test_closing_on_a_part_stops_short_and_the_switch_stays_off():
    io = DigitalIO()
    io.set_part_in_hand(True, 0.0)
    io.hand_now("close", 0.0)
    assert io.hand_state(5.0) is HandState.CLOSED and io.hand.holding(5.0)
    assert not io.sig([1001], 5.0)
    io.set_part_in_hand(False, 6.0)          # the part is taken away while the hand still closes on it
    assert io.sig([1001], 6.0 + 0.04), "the fingers close the rest of the way"


def test_hand_time_bounds():
    io = DigitalIO()
    for bad in (-0.1, math.nan, math.inf, 61.0):
        with pytest.raises(RobotError):
            io.set_hand_time(bad)
    io.set_hand_time(0.5)
    assert io.scaled(10.0, False).hand_hold_s() == pytest.approx(0.05)


def test_hand_config_is_checked():
    for kw in ({"open_signal": 1001}, {"close_signal": 1}, {"closed_switch": 5}, {"close_time_s": -1.0}):
        with pytest.raises(ValueError):
            HandConfig(**kw)


# -- the controller and its skills ---------------------------------------------------------------------------

class Rig:
    def __init__(self, **kw) -> None:
        self.ctl = Controller(**kw)
        self.ctl.connect("a")
        self.n = 0

    def send(self, line: str, now: float) -> list:
        self.n += 1
        return [o.ack for o in self.ctl.handle(f"{self.n:08x}:{line}".encode(), "a", now)]

    def run(self, until: float = 1e9) -> list:
        out = []
        while (w := self.ctl.next_wake_s()) is not None and w <= until:
            out += [o.ack for o in self.ctl.step(w)]
        return out


def test_sig_ack_carries_each_state():
    r = Rig()
    assert r.send("signal:5,2001", 0.0)[0].status is Status.DONE
    (ack,) = r.send("sig:5,-5,2001,1001,-1001", 0.0)
    assert ack.extra == ("-1,0,-1,0,-1",)


@pytest.mark.parametrize("line, code", [
    ("signal:1001", ErrorCode.ILLEGAL_SIGNAL), ("signal:0", ErrorCode.ILLEGAL_SIGNAL),
    ("signal:513", ErrorCode.ILLEGAL_SIGNAL), ("sig:2513", ErrorCode.ILLEGAL_SIGNAL),
    ("signal", ErrorCode.WRONG_ARGUMENT_COUNT), ("sig", ErrorCode.WRONG_ARGUMENT_COUNT),
    ("wait_sig:8,1", ErrorCode.ILLEGAL_SIGNAL), ("wait_sig:1001,0", ErrorCode.ILLEGAL_VALUE),
    ("wait_sig:1001,-2", ErrorCode.ILLEGAL_VALUE), ("wait_sig:1001,3601", ErrorCode.ILLEGAL_VALUE),
    ("wait_sig:1001", ErrorCode.WRONG_ARGUMENT_COUNT), ("open_hand:1", ErrorCode.WRONG_ARGUMENT_COUNT),
])
def test_bad_numbers_are_error_acks_and_the_next_command_runs(line, code):
    r = Rig()
    acks = r.send(line, 0.0) + r.send("sig:1", 0.0)
    assert [(a.status, a.error_code) for a in acks] == [(Status.ERROR, code), (Status.DONE, None)]
    assert r.ctl.io.changes_since(0)[0] == []


def test_wait_sig_wakes_at_the_switch_and_times_out():
    r = Rig(io=DigitalIO(HandConfig(close_time_s=0.3)))
    r.send("close_hand", 0.0)
    r.send("wait_sig:1001,5", 0.0)
    acks = r.run()
    assert [a.status for a in acks] == [Status.DONE, Status.DONE]
    assert acks[0].t_done_s == pytest.approx(0.05) and acks[1].t_done_s == pytest.approx(0.3)
    r.send("wait_sig:1002,0.25", 1.0)
    (ack,) = r.run()
    assert (ack.status, ack.error_code, ack.t_done_s) == (Status.ERROR, ErrorCode.SIGNAL_TIMEOUT, pytest.approx(1.25))


def test_wait_sig_sees_an_input_driven_meanwhile_and_a_stop_aborts_it():
    r = Rig()
    r.send("wait_sig:1003,10", 0.0)
    r.run(until=0.5)
    r.ctl.io.set_input(1003, True, 0.5)
    (ack,) = r.run()
    assert ack.status is Status.DONE and 0.5 <= ack.t_done_s <= 0.5 + 0.017
    r.send("wait_sig:-1003,10", 1.0)
    acks = r.send("stop", 1.2)
    assert [(a.status, a.t_done_s) for a in acks[:1]] == [(Status.ABORTED, 1.2)]


def test_hand_skill_waits_for_rest_then_holds_hand_time():
    r = Rig(time_scale=10, io=DigitalIO(hand_time_s=0.5))
    r.send("move_joints:30,-90,180,0,90,0", 0.0)
    r.send("close_hand", 0.0)
    acks = r.run()
    rest = r.ctl.trajectory.t_rest_s
    closed_at = next(c.t_s for c in r.ctl.io.changes_since(0)[0] if c.signal == 2)
    assert closed_at == pytest.approx(rest), "the hand acted on a moving arm"
    assert acks[-1].t_done_s == pytest.approx(rest + 0.05), "HAND.TIME at the time scale"


def test_deferred_hand_acts_as_the_next_motion_starts_and_not_after_a_stop():
    r = Rig(time_scale=10)
    io = r.ctl.io
    io.defer_hand("close")
    r.send("here", 0.0)
    assert not io.state(2), "a deferred CLOSE acted before any motion"
    r.send("move_joints:10,-90,180,0,90,0", 1.0)
    assert io.state(2) and changes(io)[-1][0] == 1.0
    io.defer_hand("open")
    r.send("stop", 1.0)
    r.run()
    r.send("move_joints:0,-90,180,0,90,0", 5.0)
    assert not io.state(1), "a deferred OPEN acted on the first motion after a stop"


def test_a_deferred_hand_acts_as_a_straight_line_starts_too():
    """OPEN/CLOSE act at the start of the next motion of any kind: MOVES (move_to_s) as MOVE."""
    r = Rig(time_scale=10)
    io = r.ctl.io
    io.defer_hand("close")
    r.send("move_to_s:480,0,650,0,180,0", 1.0)
    assert io.state(2) and changes(io)[-1][0] == 1.0, "the deferred CLOSE did not act as the line started"


def test_state_snapshot_carries_io_and_hand():
    r = Rig()
    r.send("signal:8,2001", 0.0)
    r.send("close_hand", 0.0)
    r.run()
    st = r.ctl.state(1.0)
    assert st.air and st.io is not None
    assert (st.io.outputs_on, st.io.inputs_on, st.io.soft_on, st.io.hand) == ((2, 8), (1001,), (2001,), "closed")


# -- a property: the model agrees with a plain dict, and its log replays to its state -------------------------

_nums = hst.one_of(hst.integers(-2600, 2600), hst.sampled_from([1, -1, 2, -2, 8, -8, 1001, -1001, 2001, -2512]))
_ops = hst.lists(hst.tuples(hst.sampled_from(["signal", "input", "hand"]), hst.lists(_nums, min_size=1, max_size=4),
                            hst.sampled_from(["open", "close", "relax"])), max_size=30)


@settings(max_examples=200, deadline=None)
@given(ops=_ops)
def test_signal_log_replays_to_the_state_and_refusals_change_nothing(ops):
    io = DigitalIO(HandConfig(closed_switch=None))   # no switch: inputs change only through set_input here
    ref: dict[int, bool] = {}
    t = 0.0
    for kind, nums, action in ops:
        t += 0.01
        if kind == "signal":
            ok = all(n != 0 and signal_kind(n) in (SignalKind.OUTPUT, SignalKind.SOFT) for n in nums)
            try:
                io.signal(nums, t)
                assert ok, nums
                ref.update({abs(n): n > 0 for n in nums})
            except RobotError:
                assert not ok, nums
        elif kind == "input":
            n = nums[0]
            ok = n > 0 and signal_kind(n) is SignalKind.INPUT
            try:
                io.set_input(n, True, t)
                assert ok, n
                ref[n] = True
            except RobotError:
                assert not ok, n
        else:
            io.hand_now(action, t)
            ref.update({1: action == "open", 2: action == "close"})
        assert {n for n, on in io.values.items() if on} == {n for n, on in ref.items() if on}
    replay: dict[int, bool] = {}
    for c in io.changes_since(0)[0]:
        assert replay.get(c.signal, False) != c.on, "a logged change that changed nothing"
        replay[c.signal] = c.on
    assert {n for n, on in replay.items() if on} == {n for n, on in ref.items() if on}
