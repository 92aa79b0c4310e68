"""``--fault raise=POINT`` (``Faults.raise_at``), the test-only hook that injects a bug of the sim's server: parsed,
checked, and refused where it could not act (docs/sim.md, "When the server dies")."""

from __future__ import annotations

import pytest

from aioadept.sim.server import RAISE_POINTS, Faults, SimOptions


@pytest.mark.parametrize("point", sorted(RAISE_POINTS))
def test_each_point_parses(point: str) -> None:
    assert Faults.parse([f"raise={point}", "ack-delay=0.5"]) == Faults(ack_delay_s=0.5, raise_at=point)


def test_an_unknown_point_names_the_points() -> None:
    with pytest.raises(ValueError, match=r"raise=execute: not a fault point \(executor, reader, world"):
        Faults.parse(["raise=execute"])


def test_no_fault_raises_nowhere() -> None:
    assert Faults.parse([]).raise_at is None


def test_a_world_fault_without_a_world_is_refused() -> None:
    # it could never fire: a test relying on it would wait for a death that does not come
    with pytest.raises(ValueError, match="raise=world needs a world"):
        SimOptions(faults=Faults(raise_at="world"))
