"""The IK jump limit is a setting of the controller, the sim's options and `aioadept sim --joint-jump-limit`."""

from __future__ import annotations


import pytest

from aioadept.protocol import ErrorCode, Status
from aioadept.cli.sim import build_parser, options_from_args
from aioadept.sim.controller import Controller
from aioadept.robots.viper_s850 import DEFAULT_JUMP_LIMIT, JumpLimit

# Just off the wrist singularity: a 1 deg tilt of the tool at right angles to the bend needs J4 to swing ~76 deg.
Q = (0.0, -90.0, 180.0, 90.0, 0.3, 0.0)
TILT = b"0000a001:move_rel_tool:0.000,0.000,0.000,90.000,1.000,-90.000"


def _tilt(ctl: Controller):
    ctl.connect("c")
    (out,) = ctl.handle(TILT, "c", now=0.0)
    return out.ack


def test_the_default_controller_refuses_the_jump_with_an_error_ack_and_does_not_move():
    ctl = Controller(joints_deg=Q, instant=True)
    ack = _tilt(ctl)
    assert ack.status is Status.ERROR and ack.error_code == ErrorCode.JOINT_JUMP
    assert ctl.joints_at(10.0) == pytest.approx(Q)


def test_a_controller_with_the_check_off_makes_the_swing():
    ctl = Controller(joints_deg=Q, instant=True, jump_limit=None)
    ack = _tilt(ctl)
    assert ack.status is Status.DONE
    assert abs(ctl.joints_at(10.0)[3] - Q[3]) > 45  # what the check exists to refuse


def test_the_cli_option_reaches_the_controller():
    parse = build_parser().parse_args
    assert options_from_args(parse([])).make_controller().jump_limit == DEFAULT_JUMP_LIMIT
    assert options_from_args(parse(["--joint-jump-limit", "off"])).make_controller().jump_limit is None
    ctl = options_from_args(parse(["--joint-jump-limit", "0.5,0.2,1"])).make_controller()
    assert ctl.jump_limit == JumpLimit(0.5, 0.2, 1.0)


@pytest.mark.parametrize("bad", ["1,2", "a,b,c", "-1,0,0", "nan,1,1"])
def test_a_bad_cli_value_is_a_usage_error_naming_the_form(bad, capsys):
    with pytest.raises(SystemExit) as info:
        build_parser().parse_args(["--joint-jump-limit", bad])
    assert info.value.code == 2
    assert "FLOOR,PER_MM,PER_DEG" in capsys.readouterr().err
