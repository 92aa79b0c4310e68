"""Fixtures of the integration tests: ``bus`` runs a bus test once per transport, and on Zenoh once more with requests
sent as queries (tests/integration/bustransports.py)."""

from __future__ import annotations

import importlib.util

import pytest

from bustransports import TRANSPORTS, BusEndpoints, start_zenoh_router


@pytest.fixture(params=TRANSPORTS)
def bus(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> BusEndpoints:
    if request.param.startswith("zenoh"):
        if importlib.util.find_spec("zenoh") is None:
            pytest.skip("the [zenoh] extra (eclipse-zenoh) is not installed")
        start_zenoh_router()
    if request.param == "zenoh-queries":  # every Communicator of the test asks with Zenoh queries
        from aioadept.bus.communicator import Communicator

        monkeypatch.setitem(Communicator.__init__.__kwdefaults__, "queries", True)
    return BusEndpoints(request.param)
