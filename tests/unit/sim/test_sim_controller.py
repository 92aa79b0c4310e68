"""The pure controller with a fake clock: V+ forward processing, break, SPEED, stop, errors, clients, skills."""

import itertools

import pytest

from aioadept.errors import RobotError
from aioadept.geometry import Pose, poses_close, rel_tool, rel_world
from aioadept.protocol import NO_ID, ErrorCode, LineFramer, Status, encode_ack, parse_ack
from aioadept.robots import viper_s850 as kin
from aioadept.sim.skills import AIR_SIGNAL, SkillResult
from aioadept.sim.controller import Controller
from aioadept.sim.motion import plan_duration

HOME = kin.HOME_JOINTS_DEG
_ids = itertools.count(1)


def line(skill: str, *args: float, id: str | None = None) -> tuple[str, bytes]:
    mid = id or "%08x" % next(_ids)
    text = f"{mid}:{skill}" + (":" + ",".join("%.3f" % a for a in args) if args else "")
    return mid, text.encode()


class Rig:
    """A controller, a fake clock and the acks per connection."""

    def __init__(self, **opts):
        self.ctl = Controller(**opts)
        self.acks: dict[str, dict] = {}

    def connect(self, *conns):
        for c in conns:
            self.ctl.connect(c)
            self.acks.setdefault(c, {})

    def _take(self, out):
        for o in out:
            # Through the wire format and back: the acks must encode.
            ack = parse_ack(encode_ack(o.ack).rstrip(b"\r\n"))
            self.acks[o.conn][ack.id] = ack
        return out

    def send(self, conn, skill, *args, now, id=None):
        mid, data = line(skill, *args, id=id)
        self._take(self.ctl.handle(data, conn, now))
        return mid

    def run_until_idle(self, limit=100.0):
        while (t := self.ctl.next_wake_s()) is not None and t <= limit:
            self._take(self.ctl.step(t))

    def ack(self, conn, mid):
        return self.acks[conn].get(mid)


@pytest.fixture
def rig():
    r = Rig()
    r.connect("a", "b")
    return r


def j1_move_duration(delta_deg, speed_pct):
    return plan_duration([delta_deg, 0, 0, 0, 0, 0], speed_pct / 100)[0]


def test_set_speed_move_break_acks_move_at_start_and_break_at_completion(rig):
    s = rig.send("a", "set_speed", 100, now=1.0)
    m = rig.send("a", "move_joints", 90, -90, 180, 0, 90, 0, now=1.0)
    b = rig.send("a", "break", now=1.0)
    assert rig.ack("a", s).status is Status.DONE
    move = rig.ack("a", m)
    assert move.status is Status.DONE and move.t_start_s == move.t_done_s == 1.0
    assert poses_close(move.pose, kin.forward(HOME), tol_mm=1e-3)  # HERE when the motion started
    assert rig.ack("a", b) is None  # the break waits for the arm
    rig.ctl.step(1.2)
    assert rig.ack("a", b) is None
    rig.run_until_idle()
    brk = rig.ack("a", b)
    assert brk.t_start_s == pytest.approx(1.0)
    assert brk.t_done_s == pytest.approx(1.0 + j1_move_duration(90, 100), abs=1e-9)
    assert poses_close(brk.pose, kin.forward([90, -90, 180, 0, 90, 0]), tol_mm=2e-3, tol_deg=2e-3)


def long_move_time(rig, speed, now):
    rig.send("a", "set_speed", speed, now=now)
    rig.send("a", "move_joints", 150, -90, 180, 0, 90, 0, now=now)
    b = rig.send("a", "break", now=now)
    rig.run_until_idle()
    t = rig.ack("a", b).t_done_s - now
    rig.send("a", "move_joints", -150, -90, 180, 0, 90, 0, now=rig.ack("a", b).t_done_s)
    b2 = rig.send("a", "break", now=rig.ack("a", b).t_done_s)
    rig.run_until_idle()
    return t, rig.ack("a", b2).t_done_s


def test_speed_50_roughly_doubles_the_cruise_time():
    rig = Rig(joints_deg=(-150, -90, 180, 0, 90, 0))
    rig.connect("a")
    t100, later = long_move_time(rig, 100, 0.0)
    t50, _ = long_move_time(rig, 50, later)
    ramp = 0.1
    assert 2.0 < (t50 - 2 * ramp) / (t100 - 2 * ramp) < 2.15
    assert t50 == pytest.approx(j1_move_duration(300, 50))


def test_speed_reverts_after_one_motion(rig):
    rig.send("a", "set_speed", 25, now=0.0)
    rig.send("a", "move_joints", 100, -90, 180, 0, 90, 0, now=0.0)
    b1 = rig.send("a", "break", now=0.0)
    rig.run_until_idle()
    t1 = rig.ack("a", b1).t_done_s
    rig.send("a", "move_joints", *HOME, now=t1)  # no set_speed: back at the ALWAYS speed, 100
    b2 = rig.send("a", "break", now=t1)
    rig.run_until_idle()
    assert t1 == pytest.approx(j1_move_duration(100, 25))
    assert rig.ack("a", b2).t_done_s - t1 == pytest.approx(j1_move_duration(100, 100))


def test_monitor_speed_scales_program_speed():
    r = Rig(monitor_speed_pct=50)
    r.connect("a")
    r.send("a", "move_joints", 100, -90, 180, 0, 90, 0, now=0.0)
    b = r.send("a", "break", now=0.0)
    r.run_until_idle()
    assert r.ack("a", b).t_done_s == pytest.approx(j1_move_duration(100, 50))


def test_time_scale_speeds_up_motion_not_the_clock():
    r = Rig(time_scale=100)
    r.connect("a")
    r.send("a", "move_joints", 100, -90, 180, 0, 90, 0, now=5.0)
    b = r.send("a", "break", now=5.0)
    r.run_until_idle()
    assert r.ack("a", b).t_done_s == pytest.approx(5.0 + j1_move_duration(100, 100) / 100)


def test_forward_processing_one_motion_deep_and_blending(rig):
    targets = [[40, -90, 180, 0, 90, 0], [80, -90, 180, 0, 90, 0], [120, -90, 180, 0, 90, 0]]
    ids = [rig.send("a", "move_joints", *t, now=0.0) for t in targets]
    b = rig.send("a", "break", now=0.0)
    # The first starts now; each next one acks when it starts, as the one before begins to decelerate.
    assert rig.ack("a", ids[0]).t_done_s == 0.0
    assert rig.ack("a", ids[1]) is None and rig.ack("a", ids[2]) is None
    rig.run_until_idle()
    d = j1_move_duration(40, 100)
    assert rig.ack("a", ids[1]).t_done_s == pytest.approx(d - 0.1)  # the 2nd starts as the 1st decelerates
    assert rig.ack("a", ids[2]).t_done_s == pytest.approx(2 * d - 0.2)
    # Blended: three 40 deg moves take less than three stop-and-go moves.
    t_blend = rig.ack("a", b).t_done_s
    assert t_blend == pytest.approx(3 * d - 2 * 0.1)
    assert poses_close(rig.ack("a", b).pose, kin.forward(targets[-1]), tol_mm=2e-3, tol_deg=2e-3)


def test_stop_during_break_aborts_queued_commands_and_acks_done_at_rest(rig):
    m = rig.send("a", "move_joints", 150, -90, 180, 0, 90, 0, now=0.0)
    b = rig.send("a", "break", now=0.0)
    queued_a = rig.send("a", "move_joints", *HOME, now=0.1)
    queued_b = rig.send("b", "enable_air", now=0.2)
    rig.ctl.step(0.3)
    s = rig.send("b", "stop", now=0.3)
    assert rig.ack("a", m).status is Status.DONE
    assert rig.ack("a", b).status is Status.ABORTED and rig.ack("a", b).t_done_s == pytest.approx(0.3)
    assert rig.ack("a", queued_a).status is Status.ABORTED
    assert rig.ack("b", queued_b).status is Status.ABORTED
    assert rig.ack("b", s) is None  # decelerating
    rig.run_until_idle()
    stop = rig.ack("b", s)
    assert stop.status is Status.DONE and stop.t_start_s == pytest.approx(0.3)
    assert stop.t_done_s == pytest.approx(0.4)  # J1 at 250 deg/s, decelerating at 2500 deg/s^2
    joints = rig.ctl.joints_at(stop.t_done_s)
    assert 0 < joints[0] < 150 and not rig.ctl.trajectory.in_motion(stop.t_done_s)
    assert rig.ctl.joints_at(10.0) == pytest.approx(joints)  # the aborted move home never ran
    # And the server goes on serving.
    h = rig.send("a", "here", now=1.0)
    assert rig.ack("a", h).status is Status.DONE


def test_stop_resets_a_pending_speed(rig):
    rig.send("a", "set_speed", 10, now=0.0)
    rig.send("a", "stop", now=0.0)
    rig.send("a", "move_joints", 100, -90, 180, 0, 90, 0, now=1.0)
    b = rig.send("a", "break", now=1.0)
    rig.run_until_idle()
    assert rig.ack("a", b).t_done_s - 1.0 == pytest.approx(j1_move_duration(100, 100))


def test_disconnect_discards_queued_commands(rig):
    rig.send("a", "move_joints", 60, -90, 180, 0, 90, 0, now=0.0)
    b = rig.send("a", "break", now=0.0)
    rig.send("a", "move_joints", -60, -90, 180, 0, 90, 0, now=0.0)
    rig.send("a", "enable_air", now=0.0)
    assert rig.ctl.queued("a") == 2
    rig.ctl.disconnect("a", now=0.1)
    assert rig.ctl.queued() == 0
    rig.run_until_idle()
    assert rig.ack("a", b) is None  # the break ran on but its client is gone
    assert rig.ctl.joints_at(10.0)[0] == pytest.approx(60)  # the started motion finished, the queued one never ran
    assert rig.ctl.air is False


def test_acks_go_to_the_sender_in_one_serial_order(rig):
    rig.send("a", "move_joints", 60, -90, 180, 0, 90, 0, now=0.0)
    b = rig.send("a", "break", now=0.0)
    h = rig.send("b", "enable_air", now=0.05)
    assert rig.ack("b", h) is None  # b's command waits behind a's break, like the single V+ task
    rig.run_until_idle()
    assert rig.ack("b", h).t_done_s == pytest.approx(rig.ack("a", b).t_done_s)
    assert h not in rig.acks["a"] and b not in rig.acks["b"]
    assert rig.ack("b", h).pose == rig.ack("a", b).pose


def test_hello_reports_protocol_version_and_server_name_in_order(rig):
    rig.send("a", "move_joints", 60, -90, 180, 0, 90, 0, now=0.0)
    b = rig.send("a", "break", now=0.0)
    h = rig.send("a", "hello", now=0.01)
    assert rig.ack("a", h) is None  # in order behind its own connection's break
    rig.run_until_idle()
    ack = rig.ack("a", h)
    assert ack.status is Status.DONE and ack.extra == ("1", f"aioadept-sim {rig.ctl.version}")
    assert ack.t_done_s == pytest.approx(rig.ack("a", b).t_done_s)


def test_immediate_user_skill_is_served_during_a_break(rig):
    rig.ctl.register("ping", lambda ctl, args: SkillResult(("pong",)), immediate=True)
    rig.send("a", "move_joints", 60, -90, 180, 0, 90, 0, now=0.0)
    rig.send("a", "break", now=0.0)
    p = rig.send("b", "ping", now=0.01)
    assert rig.ack("b", p).extra == ("pong",) and rig.ack("b", p).t_done_s == pytest.approx(0.01)


def test_air_is_digital_output_8(rig):
    rig.send("a", "enable_air", now=0.0)
    assert rig.ctl.signals[AIR_SIGNAL] is True and rig.ctl.state(0.0).air
    rig.send("a", "disable_air", now=0.0)
    assert rig.ctl.air is False


def test_move_rel_tool_and_rel_world_targets(rig):
    rig.send("a", "move_rel_joints", -90, 60, 30, -90, 0, 0, now=0.0)
    rig.send("a", "break", now=0.0)
    rig.run_until_idle()
    t = rig.ctl.now_s
    start = rig.ctl.here_at(t)
    rig.send("a", "move_rel_tool", 40, -25, 185, 0, 0, 0, now=t)
    b = rig.send("a", "break", now=t)
    rig.run_until_idle()
    assert poses_close(rig.ack("a", b).pose, rel_tool(start, (40, -25, 185, 0, 0, 0)), tol_mm=2e-3, tol_deg=2e-3)
    t = rig.ctl.now_s
    start = rig.ctl.here_at(t)
    rig.send("a", "move_rel_world", 10, 0, -20, 0, -5, 0, now=t)
    b = rig.send("a", "break", now=t)
    rig.run_until_idle()
    assert poses_close(rig.ack("a", b).pose, rel_world(start, (10, 0, -20, 0, -5, 0)), tol_mm=2e-3, tol_deg=2e-3)


def test_paper_init_move_sequence_instant():
    r = Rig(instant=True)
    r.connect("a")
    seq = [("move_joints", *HOME), ("break",), ("move_rel_joints", -90, 60, 30, -90, 0, 0), ("break",),
           ("move_rel_tool", 40, -25, 185, 0, 0, 0), ("break",), ("move_rel_joints", 0, 0, 0, 0, 0, 1.5), ("break",)]
    ids = [r.send("a", *cmd, now=0.0) for cmd in seq]
    acks = [r.ack("a", i) for i in ids]
    assert all(a is not None and a.status is Status.DONE for a in acks)
    approach = kin.forward([-90, -30, 210, -90, 90, 0])
    expected = rel_tool(approach, (40, -25, 185, 0, 0, 0)) @ Pose(0, 0, 0, 0, 0, 1.5)
    assert poses_close(acks[-1].pose, expected, tol_mm=2e-3, tol_deg=2e-3)


def test_relative_move_without_break_reads_here_mid_motion(rig):
    rig.send("a", "move_joints", 100, -90, 180, 0, 90, 0, now=0.0)
    rig.ctl.step(0.2)
    here_j1 = rig.ctl.joints_at(0.2)[0]
    rig.send("a", "move_rel_joints", 10, 0, 0, 0, 0, 0, now=0.2)
    b = rig.send("a", "break", now=0.2)
    rig.run_until_idle()
    # V+ HERE during a motion is where the arm is, so the target is HERE + 10, not 100 + 10.
    assert rig.ctl.joints_at(rig.ack("a", b).t_done_s)[0] == pytest.approx(here_j1 + 10)


@pytest.mark.parametrize("skill,args,code", [
    ("fly", (), ErrorCode.UNKNOWN_SKILL),
    ("move_to", (1, 2, 3), ErrorCode.WRONG_ARGUMENT_COUNT),
    ("break", (1,), ErrorCode.WRONG_ARGUMENT_COUNT),
    ("set_speed", (0,), ErrorCode.ILLEGAL_VALUE),
    ("set_speed", (101,), ErrorCode.ILLEGAL_VALUE),
    ("set_speed", (-5,), ErrorCode.ILLEGAL_VALUE),
    ("move_to", (2000, 0, 500, 0, 180, 0), ErrorCode.OUT_OF_REACH),
    ("move_joints", (0, -90, 180, 0, 130, 0), ErrorCode.JOINT_LIMIT),
    ("move_rel_joints", (0, 0, 100, 0, 0, 0), ErrorCode.JOINT_LIMIT),
    ("move_rel_world", (0, 0, 500, 0, 0, 0), ErrorCode.OUT_OF_REACH),
    ("move_rel_tool", (0, 0, -900, 0, 0, 0), ErrorCode.OUT_OF_REACH),
])
def test_errors_answer_error_acks_and_the_robot_does_not_move(rig, skill, args, code):
    mid = rig.send("a", skill, *args, now=0.0)
    b = rig.send("a", "break", now=0.0)
    rig.run_until_idle()
    ack = rig.ack("a", mid)
    assert ack.status is Status.ERROR and ack.error_code == code
    assert ack.error_message
    assert rig.ack("a", b).status is Status.DONE
    assert rig.ctl.joints_at(10.0) == pytest.approx(HOME)
    # The server keeps serving.
    m = rig.send("a", "move_joints", 10, -90, 180, 0, 90, 0, now=11.0)
    assert rig.ack("a", m).status is Status.DONE


@pytest.mark.parametrize("data,id,code", [
    (b"abcdef12:move_to:1,2,x,4,5,6", "abcdef12", ErrorCode.ILLEGAL_VALUE),
    (b"abcdef13:Move", "abcdef13", ErrorCode.MALFORMED_MESSAGE),
    (b"garbage", NO_ID, ErrorCode.MALFORMED_MESSAGE),
    (b"abcdef14:move_to:1:2", "abcdef14", ErrorCode.MALFORMED_MESSAGE),
])
def test_bad_lines_answer_error_acks(rig, data, id, code):
    rig._take(rig.ctl.handle(data, "a", 0.0))
    ack = rig.ack("a", id)
    assert ack.status is Status.ERROR and ack.error_code == code


def test_oversize_line_answers_line_too_long_with_its_id(rig):
    framer = LineFramer()
    data = b"abcdef15:move_to:" + b"1," * 80 + b"1\r\nabcdef16:here\r\n"
    for item in framer.feed(data):
        rig._take(rig.ctl.handle(item, "a", 0.0))
    assert rig.ack("a", "abcdef15").error_code == ErrorCode.LINE_TOO_LONG
    assert rig.ack("a", "abcdef16").status is Status.DONE


def test_errors_keep_arrival_order_per_connection(rig):
    out = []
    rig.ctl.handle(b"00000001:move_joints:30,-90,180,0,90,0", "a", 0.0)
    out += rig.ctl.handle(b"00000002:break", "a", 0.0)
    out += rig.ctl.handle(b"00000003:fly", "a", 0.0)
    out += rig.ctl.handle(b"00000004:here", "a", 0.0)
    while (t := rig.ctl.next_wake_s()) is not None:
        out += rig.ctl.step(t)
    assert [o.ack.id for o in out] == ["00000002", "00000003", "00000004"]


def test_failed_motion_consumes_the_pending_speed(rig):
    rig.send("a", "set_speed", 10, now=0.0)
    bad = rig.send("a", "move_to", 2000, 0, 0, 0, 180, 0, now=0.0)
    assert rig.ack("a", bad).status is Status.ERROR
    rig.send("a", "move_joints", 100, -90, 180, 0, 90, 0, now=0.0)
    b = rig.send("a", "break", now=0.0)
    rig.run_until_idle()
    assert rig.ack("a", b).t_done_s == pytest.approx(j1_move_duration(100, 100))


def test_user_skills_can_be_registered_and_can_wait(rig):
    def dwell(ctl, args):
        (seconds,) = args
        until = ctl.now_s + seconds
        while ctl.now_s < until:
            yield until
        return SkillResult(("dwelt",))

    rig.ctl.register("dwell", dwell, nargs=1)
    d = rig.send("a", "dwell", 0.5, now=1.0)
    h = rig.send("a", "here", now=1.0)
    assert rig.ack("a", d) is None
    rig.run_until_idle()
    assert rig.ack("a", d).t_done_s == pytest.approx(1.5) and rig.ack("a", d).extra == ("dwelt",)
    assert rig.ack("a", h).t_done_s == pytest.approx(1.5)


def test_a_crashing_user_skill_answers_skill_failed(rig):
    rig.ctl.register("oops", lambda ctl, args: 1 / 0)
    mid = rig.send("a", "oops", now=0.0)
    assert rig.ack("a", mid).error_code == ErrorCode.SKILL_FAILED
    with pytest.raises(ValueError):
        rig.ctl.register("Bad Name", lambda ctl, args: None)


def test_queue_limit_per_connection():
    r = Rig(max_queued_per_conn=2)
    r.connect("a")
    r.send("a", "move_joints", 60, -90, 180, 0, 90, 0, now=0.0)
    r.send("a", "break", now=0.0)
    r.send("a", "here", now=0.0)
    r.send("a", "here", now=0.0)
    over = r.send("a", "here", now=0.0)
    assert r.ack("a", over).error_code == ErrorCode.SERVER_BUSY


def test_state_snapshot_tracks_motion(rig):
    rig.send("a", "set_speed", 40, now=0.0)
    rig.send("a", "move_joints", 100, -90, 180, 0, 90, 0, now=0.0)
    st = rig.ctl.state(0.3)
    assert st.in_motion and st.speed_pct == 40 and 0 < st.joints_deg[0] < 100
    assert poses_close(st.pose, kin.forward(st.joints_deg), tol_mm=1e-9)
    assert not rig.ctl.state(100.0).in_motion and rig.ctl.state(100.0).speed_pct == 100


def test_constructor_validates_options():
    with pytest.raises(ValueError):
        Controller(monitor_speed_pct=0)
    with pytest.raises(RobotError, match="J3 300.000 outside"):
        Controller(joints_deg=(0, 0, 300, 0, 0, 0))
