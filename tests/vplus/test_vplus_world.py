"""The V+ emulator's hand instructions move the sim's world (docs/sim.md, "The world"), in virtual time: a deferred
CLOSE grasps as the next motion starts, the part rides along the straight lines, OPENI sets it on the table, and
SIG() reads the closed-fully switch and the feeder sensor the world drives."""

from __future__ import annotations

import pytest

from aioadept.sim.controller import Controller
from aioadept.world import Feeder, PartSpec
from aioadept.world import World
from aioadept.world import WorldConfig
from aioadept.vplus import Emulator
from aioadept.vplus.emulator import make_robot

SRC = """
.PROGRAM t()
	PARAMETER HAND.TIME = 0.05
	OPENI
	fed = SIG(1002)
	MOVES TRANS(480, 0, 400, 0, 180, 0)
	BREAK
	CLOSE
	MOVES TRANS(480, 0, 500, 0, 180, 0)
	BREAK
	gripped = SIG(-1001, -1002)
	MOVES TRANS(400, 150, 400.5, 0, 180, 0)
	OPENI
	empty = SIG(-1002)
.END
"""


def test_a_v_plus_program_picks_and_places_a_part():
    part = PartSpec(5, "cylinder", (30.0, 30.0, 40.0), x_mm=480.0, y_mm=0.0)
    world = World(WorldConfig(table_z_mm=380.0, parts=(part,), feeder=Feeder(480.0, 0.0, sensor=1002)))
    e = Emulator.from_source(SRC, strict=True, robot=make_robot(Controller(world=world)))
    e.call("t")
    g = e.globals
    assert g["fed"] == -1.0, "the part on the feeder drives its input"
    assert g["gripped"] == -1.0, "closed on the part (switch off) and the feeder empty"
    assert g["empty"] == -1.0
    kinds = [(ev.kind, ev.part) for ev in world.events_since(0)[0] if ev.kind != "sensor"]
    assert kinds == [("grasped", 5), ("released", 5)]
    grasp = next(ev for ev in world.events if ev.kind == "grasped")
    closed = next(c.t_s for c in e.controller.io.changes_since(0)[0] if c.signal == 2 and c.on)
    assert grasp.t_s == pytest.approx(closed), "the deferred CLOSE grasped as the next motion started"
    p = world.snapshot(e.time_s).part(5)
    assert not p.grasped and not p.dropped
    assert (p.pose.x, p.pose.y, p.pose.z) == pytest.approx((400.0, 150.0, 380.0), abs=1e-6)
