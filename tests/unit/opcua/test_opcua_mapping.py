"""The OPC UA server's values, decided without a server (aioadept.opcua.mapping): a state sample and a status turned
into readings with their quality and source time; a stream that stops turns Uncertain and comes back Good; what V+
does not say stays Bad with no value."""

from __future__ import annotations

import pytest

from aioadept.bus.messages import RobotState
from aioadept.geometry import Pose
from aioadept.opcua.mapping import (DEGREE, DEGREE_PER_SECOND, Identity, Quality, RobotView, unece_unit_id)
from aioadept.protocol.robotstatus import RobotStatus


def sample(t: float, joints, speed: int = 100) -> RobotState:
    return RobotState(t_s=t, wall_time_s=1_700_000_000.0 + t, joints_deg=joints, pose=Pose(0, 0, 0, 0, 0, 0),
                      speed_pct=speed)


HOME = (0.0, -90.0, 180.0, 0.0, 90.0, 0.0)


def test_units_are_the_unece_codes_opc_ua_packs() -> None:
    assert DEGREE.unit_id == 0x4444 == 17476
    assert DEGREE_PER_SECOND.unit_id == (ord("E") << 16) | (ord("9") << 8) | ord("6") == 4536630
    with pytest.raises(ValueError, match="UNECE code"):
        unece_unit_id("TOOLONG")


def test_positions_are_good_with_the_robots_time_then_uncertain_when_the_stream_stops_and_good_again() -> None:
    view = RobotView(stale_after_s=0.5)
    r = view.readings(0.0)
    assert r[("axis", 1, "ActualPosition")].quality is Quality.WAITING
    assert r[("axis", 1, "ActualPosition")].value is None
    view.on_state(sample(10.0, HOME), arrived_s=100.0)
    r = view.readings(100.1)[("axis", 2, "ActualPosition")]
    assert (r.value, r.quality, r.source_time_s) == (-90.0, Quality.GOOD, 1_700_000_010.0)
    stale = view.readings(100.6)[("axis", 2, "ActualPosition")]
    assert (stale.value, stale.quality, stale.source_time_s) == (-90.0, Quality.STALE, 1_700_000_010.0)
    view.on_state(sample(11.0, HOME), arrived_s=101.0)
    assert view.readings(101.0)[("axis", 2, "ActualPosition")].quality is Quality.GOOD


def test_speeds_come_from_consecutive_samples_on_the_robots_clock_and_not_across_a_stall() -> None:
    view = RobotView(stale_after_s=0.5)
    view.on_state(sample(1.00, HOME), arrived_s=5.0)
    assert view.readings(5.0)[("axis", 1, "ActualSpeed")].quality is Quality.WAITING
    moved = (1.0,) + HOME[1:5] + (-2.0,)
    view.on_state(sample(1.02, moved), arrived_s=5.3)   # arrival jitter does not matter: the robot's t_s does
    r = view.readings(5.3)
    assert r[("axis", 1, "ActualSpeed")].value == pytest.approx(50.0)
    assert r[("axis", 6, "ActualSpeed")].value == pytest.approx(-100.0)
    assert r[("axis", 2, "ActualSpeed")].value == pytest.approx(0.0)
    assert r[("axis", 1, "ActualSpeed")].quality is Quality.GOOD
    # A stall: the next sample's difference spans the gap, so there is no speed until the one after it.
    view.on_state(sample(3.0, HOME), arrived_s=7.0)
    assert view.readings(7.0)[("axis", 1, "ActualSpeed")].value is None
    view.on_state(sample(3.02, moved), arrived_s=7.02)
    assert view.readings(7.02)[("axis", 1, "ActualSpeed")].value == pytest.approx(50.0)


def test_safety_says_the_estop_from_status_and_nothing_v_plus_does_not_expose() -> None:
    view = RobotView()
    r = view.readings(0.0)
    assert r[("safety", "EmergencyStop")].quality is Quality.WAITING
    for name in ("ProtectiveStop", "OperationalMode"):
        assert (r[("safety", name)].value, r[("safety", name)].quality) == (None, Quality.NOT_EXPOSED)
    view.on_status(RobotStatus(moving=False, speed_pct=100, estop=True), now_s=1_700_000_000.0)
    es = view.readings(0.0)[("safety", "EmergencyStop")]
    assert (es.value, es.quality, es.source_time_s) == (True, Quality.GOOD, 1_700_000_000.0)
    view.on_status(None)   # the server stopped answering: the last answer, Uncertain
    assert view.readings(0.0)[("safety", "EmergencyStop")].quality is Quality.STALE
    view.on_status(RobotStatus(moving=False, speed_pct=100))   # a server that does not say es=
    assert view.readings(0.0)[("safety", "EmergencyStop")].quality is Quality.NOT_EXPOSED


def test_the_controllers_software_and_task_are_the_servers_hello() -> None:
    view = RobotView()
    assert view.readings(0.0)[("software", "Model")].quality is Quality.WAITING
    view.on_hello((1, "aioadept-sim 0.1.0"))
    r = view.readings(0.0)
    assert (r[("software", "Model")].value, r[("software", "SoftwareRevision")].value) == ("aioadept-sim 0.1.0", "1")
    assert (r[("task", "TaskProgramName")].value, r[("task", "TaskProgramLoaded")].value) == \
        ("aioadept-sim 0.1.0", True)
    view.on_hello(None)
    assert view.readings(0.0)[("task", "TaskProgramLoaded")].quality is Quality.STALE
    view.on_hello((None, ""))   # the original AdeptServer: no name, no version
    assert view.readings(0.0)[("software", "Model")].quality is Quality.NOT_EXPOSED


def test_a_sample_with_another_number_of_joints_is_refused_and_bad_settings_too() -> None:
    view = RobotView(Identity(name="R", axes=6))
    with pytest.raises(ValueError, match="5 joints, R has 6 axes"):
        view.on_state(sample(0.0, HOME[:5]), arrived_s=0.0)
    with pytest.raises(ValueError, match="stale_after_s"):
        RobotView(stale_after_s=0)
    assert Identity().text("").quality is Quality.NOT_EXPOSED
