"""How asyncua's subscriptions serve the server's own values (aioadept.opcua.subscriptions): a monitored item with a
queue of one (a client asked 0 or 1, revised to 1 as OPC UA Part 4 says) is sampled once per publishing cycle and
hears no write; an item with a queue hears every write; both get the same notifications as through the library's own
path (a change is queued, a value that did not change is not, a disabled item gets nothing), without a copy of the
value. Real asyncua subscriptions and address space, no server or socket: each publishing cycle is called by hand."""

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

    from aioadept.opcua.subscriptions import SharedDataValue, install

    install()
    install()  # once per process, however many servers
    got = {}
    for cls in (ua.DataValue, SharedDataValue):
        srv, item, queue = service()
        sequence = [value(cls, 1.0), value(cls, 1.0), value(cls, 2.0), value(cls, 2.0, ua.StatusCodes.BadNotSupported)]
        for v in sequence:
            await srv.datachange_callback(3, v)
        item.mode = ua.MonitoringMode.Disabled
        await srv.datachange_callback(3, value(cls, 3.0))
        got[cls] = [(mid, handle, (v.Value.Value, v.StatusCode.value), size) for mid, handle, v, size in queue.queued]
        if cls is SharedDataValue:
            assert queue.queued[0][2] is sequence[0]            # the value written, not a copy of it
            assert item.mvalue.current_dvalue is sequence[-1]
            assert copy.deepcopy(sequence[0]) is sequence[0]
    # A change, the same value again (nothing), another change, a change of status; nothing once disabled.
    assert got[ua.DataValue] == got[SharedDataValue] == [
        (7, 42, (1.0, 0), 1), (7, 42, (2.0, 0), 1), (7, 42, (2.0, ua.StatusCodes.BadNotSupported), 1)]


class Cell:
    """One variable in a real asyncua address space, one real subscription on it (publishing by hand)."""

    def __init__(self, first) -> None:
        from asyncua import ua
        from asyncua.server.address_space import AddressSpace, AttributeValue, NodeData
        from asyncua.server.internal_subscription import InternalSubscription

        self.nodeid = ua.NodeId("Axis1.ActualPosition", 2)
        self.aspace = AddressSpace()
        node = NodeData(self.nodeid)
        node.attributes[ua.AttributeIds.Value] = AttributeValue(first)
        self.aspace[self.nodeid] = node
        self.published: list = []
        data = ua.CreateSubscriptionResult(SubscriptionId=1, RevisedPublishingInterval=100.0,
                                           RevisedLifetimeCount=10_000, RevisedMaxKeepAliveCount=10_000)
        self.sub = InternalSubscription(data, self.aspace, self._published, ua.NodeId(1, 1))

    async def _published(self, result) -> None:
        self.published.append(result)

    async def monitor(self, queue_size: int, handle: int):
        from asyncua import ua

        item = ua.MonitoredItemCreateRequest(
            ItemToMonitor=ua.ReadValueId(NodeId=self.nodeid, AttributeId=ua.AttributeIds.Value),
            MonitoringMode=ua.MonitoringMode.Reporting,
            RequestedParameters=ua.MonitoringParameters(ClientHandle=handle, QueueSize=queue_size))
        (result,) = await self.sub.monitored_item_srv.create_monitored_items(
            ua.CreateMonitoredItemsParameters(ItemsToCreate=[item]))
        return result

    async def write(self, *values) -> None:
        from asyncua import ua

        for v in values:
            await self.aspace.write_attribute_value(self.nodeid, ua.AttributeIds.Value, v)

    def callbacks(self) -> int:
        from asyncua import ua

        return len(self.aspace[self.nodeid].attributes[ua.AttributeIds.Value].datachange_callbacks)

    async def cycle(self) -> dict[int, list]:
        """One publishing cycle: each client handle's values in it (value, status code)."""
        self.published.clear()
        await self.sub.publish_results()
        out: dict[int, list] = {}
        for result in self.published:
            for data in result.NotificationMessage.NotificationData:
                for n in data.MonitoredItems:
                    out.setdefault(n.ClientHandle, []).append((n.Value.Value.Value, n.Value.StatusCode.value))
        return out


async def test_a_queue_of_one_is_sampled_once_per_publish_and_a_queue_hears_every_write() -> None:
    from asyncua import ua

    from aioadept.opcua.subscriptions import SharedDataValue, install

    install()
    cell = Cell(value(SharedDataValue, 1.0))
    one, zero, five = await cell.monitor(1, 11), await cell.monitor(0, 10), await cell.monitor(5, 50)
    # Part 4, 7.16: 0 or 1 is a queue of one; the sampled items are off the write path, the queued one on it.
    assert (one.RevisedQueueSize, zero.RevisedQueueSize, five.RevisedQueueSize) == (1, 1, 5)
    assert cell.callbacks() == 1
    assert await cell.cycle() == {11: [(1.0, 0)], 10: [(1.0, 0)], 50: [(1.0, 0)]}  # the first values

    written = [value(SharedDataValue, x) for x in (2.0, 3.0, 4.0)]
    await cell.write(*written)  # three samples between two publishes
    got = await cell.cycle()
    assert got[11] == got[10] == [(4.0, 0)]                      # the newest, once
    assert got[50] == [(2.0, 0), (3.0, 0), (4.0, 0)]              # every sample, in order
    assert cell.sub.monitored_item_srv._monitored_items[one.MonitoredItemId].mvalue.current_dvalue is written[-1]

    assert await cell.cycle() == {}                               # nothing written: nothing sent
    await cell.write(value(SharedDataValue, 4.0))                 # the same value again: no change to report
    assert await cell.cycle() == {}
    await cell.write(value(SharedDataValue, 4.0, ua.StatusCodes.UncertainNoCommunicationLastUsableValue))
    got = await cell.cycle()
    assert got[11] == got[50] == [(4.0, ua.StatusCodes.UncertainNoCommunicationLastUsableValue)]

    # Disabled: nothing, and the value is taken again once enabled.
    srv = cell.sub.monitored_item_srv
    await srv.set_monitoring_mode(ua.MonitoringMode.Disabled, [one.MonitoredItemId])
    await cell.write(value(SharedDataValue, 5.0))
    assert 11 not in await cell.cycle()
    await srv.set_monitoring_mode(ua.MonitoringMode.Reporting, [one.MonitoredItemId])
    assert (await cell.cycle())[11] == [(5.0, 0)]

    # A queue asked later puts the item back on the write path; a deleted item is sampled no more.
    modify = ua.MonitoredItemModifyRequest(MonitoredItemId=one.MonitoredItemId,
                                           RequestedParameters=ua.MonitoringParameters(ClientHandle=11, QueueSize=3))
    (modified,) = srv.modify_monitored_items(ua.ModifyMonitoredItemsParameters(ItemsToModify=[modify]))
    assert modified.RevisedQueueSize == 3 and cell.callbacks() == 2
    srv.delete_monitored_items([zero.MonitoredItemId])
    await cell.write(value(SharedDataValue, 6.0), value(SharedDataValue, 7.0))
    assert await cell.cycle() == {11: [(6.0, 0), (7.0, 0)], 50: [(6.0, 0), (7.0, 0)]}


def test_a_shared_value_is_encoded_once_into_a_data_value_s_bytes() -> None:
    from asyncua import ua
    from asyncua.ua.ua_binary import struct_to_binary

    from aioadept.opcua.subscriptions import SharedDataValue, install

    install()
    shared, plain = value(SharedDataValue, 12.5, ua.StatusCodes.UncertainNoCommunicationLastUsableValue), \
        value(ua.DataValue, 12.5, ua.StatusCodes.UncertainNoCommunicationLastUsableValue)
    expected = struct_to_binary(ua.MonitoredItemNotification(ClientHandle=9, Value=plain))
    first = struct_to_binary(ua.MonitoredItemNotification(ClientHandle=9, Value=shared))
    assert first == expected
    assert shared._binary is not None                          # kept on the value for the next subscriber
    assert struct_to_binary(ua.MonitoredItemNotification(ClientHandle=9, Value=shared)) == expected


def publish_responses() -> list:
    """PublishResponses as asyncua's server sends them, and every part the fast encoding leaves to the library."""
    from asyncua import ua

    from aioadept.opcua.subscriptions import SharedDataValue

    def response(notifications, handle: int = 7, **result) -> ua.PublishResponse:
        fields = {"SubscriptionId": 3, "AvailableSequenceNumbers": [4, 5], "MoreNotifications": False,
                  "Results": [ua.StatusCode()], **result}
        r = ua.PublishResponse(Parameters=ua.PublishResult(**fields))
        r.Parameters.NotificationMessage.SequenceNumber = 5
        r.Parameters.NotificationMessage.NotificationData = notifications
        r.ResponseHeader.RequestHandle = handle
        return r

    def changes(cls, n: int = 6, **kw) -> ua.DataChangeNotification:
        return ua.DataChangeNotification(MonitoredItems=[ua.MonitoredItemNotification(
            ClientHandle=100 + i, Value=value(cls, 10.5 * i, ua.StatusCodes.UncertainNoCommunicationLastUsableValue
                                              if i == 2 else 0)) for i in range(n)], **kw)

    keep_alive = response([], AvailableSequenceNumbers=[])
    odd_header = response([changes(SharedDataValue)])
    odd_header.ResponseHeader.ServiceResult = ua.StatusCode(ua.StatusCodes.BadTooManyPublishRequests)
    odd_header.ResponseHeader.StringTable = ["why"]
    odd_header.ResponseHeader.ServiceDiagnostics = ua.DiagnosticInfo(SymbolicId=1, AdditionalInfo="more")
    events = ua.EventNotificationList(Events=[ua.EventFieldList(ClientHandle=9, EventFields=[ua.Variant(1.5)])])
    status = ua.StatusChangeNotification(Status=ua.StatusCode(ua.StatusCodes.BadTimeout))
    return [
        response([changes(SharedDataValue)]),
        response([changes(ua.DataValue, 3)], 2 ** 32 - 1),
        keep_alive,
        response([changes(SharedDataValue, 2), events, status],
                 Results=[ua.StatusCode(), ua.StatusCode(ua.StatusCodes.BadSequenceNumberUnknown)]),
        odd_header,
        response([changes(SharedDataValue, 1, DiagnosticInfos=[ua.DiagnosticInfo(InnerStatusCode=ua.StatusCode(
            ua.StatusCodes.BadInternalError))])], DiagnosticInfos=[ua.DiagnosticInfo(Locale=2)]),
        response([changes(SharedDataValue, 0, DiagnosticInfos=None)], Results=None, DiagnosticInfos=None,
                 AvailableSequenceNumbers=None),
        response(None),
    ]


def test_a_publish_response_is_encoded_into_the_library_s_bytes_and_decodes_back() -> None:
    from asyncua import ua
    from asyncua.common.utils import Buffer
    from asyncua.ua.ua_binary import struct_from_binary, struct_to_binary

    from aioadept.opcua import subscriptions

    subscriptions.install()
    library = subscriptions.library_serializer(ua.PublishResponse)
    for response in publish_responses():
        data = struct_to_binary(response)
        assert data == library(response)
        back = struct_from_binary(ua.PublishResponse, Buffer(data))
        assert struct_to_binary(back) == data
        items = [i for n in back.Parameters.NotificationMessage.NotificationData or ()
                 if isinstance(n, ua.DataChangeNotification) for i in n.MonitoredItems]
        sent = [i for n in response.Parameters.NotificationMessage.NotificationData or ()
                if isinstance(n, ua.DataChangeNotification) for i in n.MonitoredItems]
        assert [(i.ClientHandle, i.Value.Value, i.Value.StatusCode, i.Value.SourceTimestamp) for i in items] == \
            [(i.ClientHandle, i.Value.Value, i.Value.StatusCode, i.Value.SourceTimestamp) for i in sent]


def subscription(sid: int, interval_ms: float, published: list, *, lifetime: int = 10_000, request=None,
                 deleted: list | None = None):
    """A real asyncua subscription whose publishes (keep-alives every cycle) land in ``published``."""
    from asyncua import ua
    from asyncua.server.address_space import AddressSpace
    from asyncua.server.internal_subscription import InternalSubscription

    async def callback(result, *requestdata) -> None:
        if sid == 666:
            raise RuntimeError("a publish that raises")
        published.append(sid)

    data = ua.CreateSubscriptionResult(SubscriptionId=sid, RevisedPublishingInterval=interval_ms,
                                       RevisedLifetimeCount=lifetime, RevisedMaxKeepAliveCount=1)
    return InternalSubscription(data, AddressSpace(), callback, ua.NodeId(1, 1), request_callback=request,
                                delete_callback=None if deleted is None else (lambda: deleted.append(sid)))


async def test_subscriptions_with_one_publishing_interval_share_one_timer() -> None:
    import asyncio

    from asyncua import ua

    from aioadept.opcua.subscriptions import install

    install()
    before = len(asyncio.all_tasks())
    published: list[int] = []
    deleted: list[int] = []
    subs = [subscription(i, 40.0, published) for i in range(1, 21)]
    subs.append(subscription(666, 40.0, published))  # its publish raises: logged, the others go on
    # No publish request ever comes: it expires after its lifetime count of cycles, as with its own task.
    expiring = subscription(99, 40.0, published, lifetime=2, request=lambda sid: None, deleted=deleted)
    subs.append(expiring)
    other = subscription(50, 15.0, published)
    for sub in [*subs, other]:
        await sub.start()
    assert published == []  # the first publish comes after the CreateSubscription response, not inside start
    await asyncio.sleep(0)
    await asyncio.sleep(0)
    # Each published once at start; one timer per publishing interval, not a task per subscription.
    assert sorted(published) == [*range(1, 21), 50]
    assert len(asyncio.all_tasks()) - before == 2

    await asyncio.sleep(0.37)
    counts = {sid: published.count(sid) for sid in set(published)}
    assert all(5 <= counts[i] <= 11 for i in range(1, 21)), counts    # 1 + about 9 cycles of 40 ms
    assert counts[50] >= 12, counts                                   # 1 + about 24 cycles of 15 ms
    assert deleted == [99] and expiring._triggered_statuschanges == [ua.StatusCode(ua.StatusCodes.BadTimeout)]

    for sub in subs[:10]:
        await sub.stop()
    published.clear()
    await asyncio.sleep(0.1)
    assert {*published} == {*range(11, 21), 50}                       # a stopped subscription is published no more
    for sub in [*subs[10:], other]:
        await sub.stop()
    await asyncio.sleep(0.05)
    assert len(asyncio.all_tasks()) == before                         # no subscription left: no timer left
    published.clear()
    await subs[0].start()                                              # and a new one gets a timer again
    await asyncio.sleep(0.1)
    assert published.count(1) >= 2
    await subs[0].stop()
