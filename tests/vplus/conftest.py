"""Fixtures shared by the V+ emulator tests."""

from __future__ import annotations

from typing import Any, Callable

import pytest

from aioadept.vplus import Emulator


@pytest.fixture
def emu_of() -> Callable[..., Emulator]:
    """Builds an emulator of V+ source text with no robot, loaded as ``t.V2``; strict unless ``strict=False``
    (a test of load problems wants them in ``emu.problems`` instead of raised)."""
    def build(src: str, **options: Any) -> Emulator:
        return Emulator.from_source(src, **{"filename": "t.V2", "robot": False, "strict": True, **options})
    return build
