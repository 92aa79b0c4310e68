"""Fixtures of the integration tests: ``bus`` runs a bus test once per transport (tests/integration/bustransports.py)."""

from __future__ import annotations

import importlib.util

import pytest

from bustransports import TRANSPORTS, BusEndpoints, start_zenoh_router


@pytest.fixture(params=TRANSPORTS)
def bus(request: pytest.FixtureRequest) -> BusEndpoints:
    if request.param == "zenoh":
        if importlib.util.find_spec("zenoh") is None:
            pytest.skip("the [zenoh] extra (eclipse-zenoh) is not installed")
        start_zenoh_router()
    return BusEndpoints(request.param)
