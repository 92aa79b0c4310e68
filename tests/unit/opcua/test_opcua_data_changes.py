"""The server's short path for its own values through asyncua's monitored items (aioadept.opcua.server
``_lean_data_changes``): a subscriber gets the same notifications as through the library's own path (a change is
queued, a value that did not change is not, a disabled item gets nothing), without a copy of the value."""

from __future__ import annotations

import copy
import datetime
from types import SimpleNamespace

import pytest

pytest.importorskip("asyncua")


class Queue:
    def __init__(self) -> None:
        self.queued: list = []

    async def enqueue_datachange_event(self, mid, event, size) -> None:
        self.queued.append((mid, event.ClientHandle, event.Value, size))


def service():
    from asyncua.server.monitored_item_service import MonitoredItemData, MonitoredItemService
    from asyncua import ua

    queue = Queue()
    srv = MonitoredItemService(SimpleNamespace(data=SimpleNamespace(SubscriptionId=1), **{
        "enqueue_datachange_event": queue.enqueue_datachange_event}), None)
    item = MonitoredItemData()
    item.client_handle, item.mode, item.queue_size = 42, ua.MonitoringMode.Reporting, 1
    srv._monitored_items[7] = item
    srv._monitored_datachange[3] = 7
    return srv, item, queue


def value(cls, v: float, status: int = 0):
    from asyncua import ua

    return cls(ua.Variant(v, ua.VariantType.Double), StatusCode=ua.StatusCode(status),
               SourceTimestamp=datetime.datetime(2026, 1, 1, tzinfo=datetime.timezone.utc))


async def test_the_server_s_own_values_give_the_same_notifications_without_a_copy() -> None:
    from asyncua import ua

    from aioadept.opcua.server import _lean_data_changes, _SharedDataValue

    _lean_data_changes()
    _lean_data_changes()  # once per process, however many servers
    got = {}
    for cls in (ua.DataValue, _SharedDataValue):
        srv, item, queue = service()
        sequence = [value(cls, 1.0), value(cls, 1.0), value(cls, 2.0), value(cls, 2.0, ua.StatusCodes.BadNotSupported)]
        for v in sequence:
            await srv.datachange_callback(3, v)
        item.mode = ua.MonitoringMode.Disabled
        await srv.datachange_callback(3, value(cls, 3.0))
        got[cls] = [(mid, handle, (v.Value.Value, v.StatusCode.value), size) for mid, handle, v, size in queue.queued]
        if cls is _SharedDataValue:
            assert queue.queued[0][2] is sequence[0]            # the value written, not a copy of it
            assert item.mvalue.current_dvalue is sequence[-1]
            assert copy.deepcopy(sequence[0]) is sequence[0]
    # A change, the same value again (nothing), another change, a change of status; nothing once disabled.
    assert got[ua.DataValue] == got[_SharedDataValue] == [
        (7, 42, (1.0, 0), 1), (7, 42, (2.0, 0), 1), (7, 42, (2.0, ua.StatusCodes.BadNotSupported), 1)]
