"""How asyncua's subscriptions serve this server's own values: what a subscribed client costs the server.

asyncua notifies every monitored item of a node at every write of it (a Python call, a trigger check and a queued
notification per item and per write), deep-copies the value each time in case the writer changes it later, and takes
a requested queue size of 0 as "no limit". With 20 clients subscribed at 100 ms to six axes that move at the state
rate (50 Hz), that was 6000 item notifications a second, five of every six of them sent and then superseded within the
same publish. :func:`install` changes three things, for the values this server writes (:class:`SharedDataValue`, which
it never changes after writing) and nothing else:

- **Sampled at the publishing interval.** A data monitored item whose queue holds one value (a client asked 0 or 1:
  OPC UA Part 4, 7.16 MonitoringParameters, "the Server returns the default queue size which shall be 1 ... The queue
  has a single entry, effectively disabling queuing") no longer hears every write: its subscription looks at the
  node's value once per publishing cycle, the revised sampling interval asyncua gives every item, and queues it when
  it differs from the last one it took (the same trigger and deadband checks). A write costs no client anything; a
  publish costs one identity check per item. Every value still carries its own source timestamp.
- **Every sample for a client that asks a queue** (queue size above 1): such an item hears every write as before, on a
  shorter path: no copy of the value, the notification made once (the library made an empty one, with its own
  DataValue and Variant, then filled it).
- A requested queue size of 0 is revised to 1, as Part 4 says, for every data monitored item.

And a value is encoded once for every subscriber that gets it, not once each; a PublishResponse is encoded by its
fixed layout rather than field by field (the same bytes); a PublishRequest is answered without first comparing its
type id with every other service's; every subscription with the same publishing interval is served by one timer
(:class:`_Cycles`) instead of a task each.

Installed once per process (:func:`install`); every other value and item goes the library's own way.
"""

from __future__ import annotations

import asyncio
import copy
import logging
import struct
import time
import weakref
from typing import Any

from asyncua import ua

__all__ = ["SharedDataValue", "install"]


class SharedDataValue(ua.DataValue):
    """A DataValue this server never changes once written: shared with every subscriber instead of copied (it is its
    own deep copy), and encoded once for all of them (:func:`_encoded_once`); the bytes are any DataValue's."""

    __slots__ = ("_binary",)

    def __deepcopy__(self, memo: dict) -> SharedDataValue:
        return self


library_serializer: Any = None
"""asyncua's own ``create_dataclass_serializer``, once :func:`install` has put this module's in its place."""


def _encoded_once() -> None:
    """asyncua's binary encoding of a :class:`SharedDataValue`: the library's DataValue encoding, made at the first
    publish that carries the value and kept on it for every other subscriber's (about 20 us a value in Python, six
    values per publish, ten publishes a second per client); and of a PublishResponse, :func:`_publish_response`."""
    from asyncua.ua import ua_binary

    global library_serializer
    library = library_serializer = ua_binary.create_dataclass_serializer
    encode = library(ua.DataValue)

    def encode_once(value: SharedDataValue) -> bytes:
        data = getattr(value, "_binary", None)
        if data is None:
            data = value._binary = encode(value)
        return data

    def data_value(value: ua.DataValue) -> bytes:
        return encode_once(value) if type(value) is SharedDataValue else encode(value)  # type: ignore[arg-type]

    publish_response = _publish_response(library, data_value)

    def serializer(cls: type) -> Any:
        if cls is SharedDataValue:
            return encode_once
        return publish_response if cls is ua.PublishResponse else library(cls)

    ua_binary.create_dataclass_serializer = serializer


def _publish_response(library: Any, data_value: Any) -> Any:
    """asyncua's binary encoding of a PublishResponse, the same bytes in a fifth of the time for the response every
    publish sends: asyncua walks each nested structure field by field through generic serializers (about 50 us a
    response here, two hundred responses a second for 20 clients at 100 ms); this writes the fixed layout of OPC UA
    Part 6 (5.2.2, 5.2.6) directly. A response header with diagnostics, a string table or an additional header, a
    notification other than a DataChangeNotification, any type id but the response's own: the library's encoding,
    for that part or the whole."""
    from asyncua.ua.ua_binary import (Primitives, Primitives1, create_list_serializer, extensionobject_to_binary,
                                      nodeid_to_binary)

    whole = library(ua.PublishResponse)
    header = library(ua.ResponseHeader)
    plain = ua.ResponseHeader()
    plain_tail = header(plain)[16:]  # the empty ServiceDiagnostics, StringTable and AdditionalHeader
    type_id = ua.PublishResponse().TypeId
    type_id_bytes = nodeid_to_binary(type_id)
    change_id = nodeid_to_binary(ua.typeid_by_extension_objects[ua.DataChangeNotification]) + b"\x01"
    u32, i32, boolean = struct.Struct("<I").pack, struct.Struct("<i").pack, struct.Struct("<?").pack
    time = Primitives.DateTime.pack
    u32_array = Primitives1.UInt32.pack_array
    absent = i32(-1)

    diagnostics = create_list_serializer(ua.DiagnosticInfo)

    def notification(n: Any) -> bytes:
        if type(n) is not ua.DataChangeNotification or n.MonitoredItems is None:
            return extensionobject_to_binary(n)
        items = n.MonitoredItems
        body = b"".join([i32(len(items)), *[u32(i.ClientHandle) + data_value(i.Value) for i in items],
                         diagnostics(n.DiagnosticInfos)])
        return change_id + i32(len(body)) + body

    def encode(response: ua.PublishResponse) -> bytes:
        h, p = response.ResponseHeader, response.Parameters
        t = response.TypeId
        if t.Identifier != type_id.Identifier or t.NamespaceIndex or t.NodeIdType != type_id.NodeIdType:
            return whole(response)
        if h.StringTable == [] and h.ServiceDiagnostics == plain.ServiceDiagnostics and \
                h.AdditionalHeader == plain.AdditionalHeader:
            head = time(h.Timestamp) + u32(h.RequestHandle) + u32(h.ServiceResult.value) + plain_tail
        else:
            head = header(h)
        m = p.NotificationMessage
        data = m.NotificationData
        results = p.Results
        return b"".join([
            type_id_bytes, head, u32(p.SubscriptionId), u32_array(p.AvailableSequenceNumbers),
            boolean(p.MoreNotifications), u32(m.SequenceNumber), time(m.PublishTime),
            absent if data is None else i32(len(data)) + b"".join([notification(n) for n in data]),
            absent if results is None else i32(len(results)) + b"".join([u32(r.value) for r in results]),
            diagnostics(p.DiagnosticInfos)])

    return encode


def _reported(service: Any, mdata: Any, value: ua.DataValue) -> bool:
    """Take ``value`` as ``mdata``'s newest value; whether it is a change to report (the library's trigger and
    deadband checks)."""
    values = mdata.mvalue
    values.old_dvalue, values.current_dvalue = values.current_dvalue, value
    if mdata.filter:
        return service._is_data_changed(values, mdata.filter.Trigger) and \
            service._is_deadband_exceeded(values, mdata.filter)
    return service._is_data_changed(values, ua.DataChangeTrigger.StatusValue)


def _sampled(service: Any) -> dict[int, list]:
    """The service's items sampled at publishing: monitored item id -> [node id, attribute, the value last taken, the
    node's attribute (asyncua's AttributeValue, whose ``value`` each write replaces)]."""
    return service.__dict__.setdefault("_aioadept_sampled", {})


def _held(aspace: Any, nodeid: ua.NodeId, attr: int) -> Any:
    """The attribute ``attr`` of ``nodeid`` as the address space holds it: read once per publish for every sampled
    item, directly rather than through the node id's lookup (a NodeId hashes in Python)."""
    node = aspace.get(nodeid)
    return None if node is None else node.attributes.get(attr)


async def sample(service: Any) -> int:
    """Queue a notification for each item of ``service`` (a subscription's MonitoredItemService) sampled at
    publishing whose node holds a value it has not taken yet and that is a change to report; returns how many."""
    queued = 0
    for mid, entry in list(_sampled(service).items()):
        nodeid, attr, seen, held = entry
        value = None if held is None else held.value
        if value is None or held.value_callback is not None:  # what the library's read makes of it
            value = service.aspace.read_attribute_value(nodeid, attr)
        if value is seen:
            continue
        entry[2] = value
        mdata = service._monitored_items.get(mid)
        if mdata is None or mdata.mode == ua.MonitoringMode.Disabled:
            continue
        if type(value) is not SharedDataValue:  # somebody else's value: copied, as the library does
            value = copy.deepcopy(value)
        if _reported(service, mdata, value):
            await service.isub.enqueue_datachange_event(
                mid, ua.MonitoredItemNotification(ClientHandle=mdata.client_handle, Value=value), mdata.queue_size)
            queued += 1
    return queued


def install() -> None:
    """Change asyncua's subscriptions as the module says (idempotent, process-wide)."""
    from asyncua.server.internal_subscription import InternalSubscription
    from asyncua.server.monitored_item_service import MonitoredItemService

    if getattr(MonitoredItemService.datachange_callback, "_aioadept", False):
        return
    library_callback = MonitoredItemService.datachange_callback
    library_create = MonitoredItemService._create_data_change_monitored_item
    library_modify = MonitoredItemService._modify_monitored_item
    library_delete = MonitoredItemService._delete_monitored_items
    library_publish = InternalSubscription.publish_results

    async def datachange_callback(self: Any, handle: int, value: ua.DataValue, error: Any = None) -> None:
        if error or type(value) is not SharedDataValue:
            return await library_callback(self, handle, value, error)
        mid = self._monitored_datachange[handle]
        mdata = self._monitored_items[mid]
        if mdata.mode == ua.MonitoringMode.Disabled:
            return None
        if _reported(self, mdata, value):
            await self.isub.enqueue_datachange_event(
                mid, ua.MonitoredItemNotification(ClientHandle=mdata.client_handle, Value=value), mdata.queue_size)
        return None

    async def create(self: Any, params: ua.MonitoredItemCreateRequest) -> ua.MonitoredItemCreateResult:
        result = await library_create(self, params)  # with the item's first value queued
        if not result.StatusCode.is_good() or params.RequestedParameters.QueueSize > 1:
            return result
        mdata = self._monitored_items[result.MonitoredItemId]
        mdata.queue_size = result.RevisedQueueSize = 1
        item = params.ItemToMonitor
        if type(mdata.mvalue.current_dvalue) is SharedDataValue:
            self.aspace.delete_datachange_callback(mdata.callback_handle)
            _sampled(self)[result.MonitoredItemId] = [item.NodeId, item.AttributeId, mdata.mvalue.current_dvalue,
                                                      _held(self.aspace, item.NodeId, item.AttributeId)]
        return result

    def modify(self: Any, params: ua.MonitoredItemModifyRequest) -> ua.MonitoredItemModifyResult:
        result = library_modify(self, params)
        mdata = self._monitored_items.get(params.MonitoredItemId)
        if mdata is None or not result.StatusCode.is_good():
            return result
        if params.RequestedParameters.QueueSize <= 1:
            mdata.queue_size = result.RevisedQueueSize = 1
        entry = _sampled(self).get(params.MonitoredItemId)
        if entry is not None and mdata.queue_size > 1:  # a queue asked now: every write from here on
            del _sampled(self)[params.MonitoredItemId]
            self._monitored_datachange.pop(mdata.callback_handle, None)
            _, mdata.callback_handle = self.aspace.add_datachange_callback(entry[0], entry[1], self.datachange_callback)
            self._monitored_datachange[mdata.callback_handle] = params.MonitoredItemId
        return result

    def delete(self: Any, mid: int) -> ua.StatusCode:
        _sampled(self).pop(mid, None)
        return library_delete(self, mid)

    async def publish_results(self: Any, requestdata: Any = None) -> bool:
        await sample(self.monitored_item_srv)
        return await library_publish(self, requestdata)

    _encoded_once()
    _publish_requests_first()
    _one_timer_per_interval(InternalSubscription)
    datachange_callback._aioadept = True  # type: ignore[attr-defined]
    MonitoredItemService.datachange_callback = datachange_callback  # type: ignore[method-assign]
    MonitoredItemService._create_data_change_monitored_item = create  # type: ignore[method-assign]
    MonitoredItemService._modify_monitored_item = modify  # type: ignore[method-assign]
    MonitoredItemService._delete_monitored_items = delete  # type: ignore[method-assign]
    InternalSubscription.publish_results = publish_results  # type: ignore[method-assign]


def _publish_requests_first() -> None:
    """asyncua's server answers a PublishRequest after comparing its type id with 35 others, each a NodeId made
    anew for the comparison (about 50 us a request here, two hundred requests a second for 20 clients at 100 ms).
    A PublishRequest of an activated session now takes the library's own steps for it without that walk: the
    permission check, the session's activity, the acknowledgements, then the publish or the queued request. Every
    other request, and a PublishRequest without an activated session (refused as before), goes the library's way."""
    from asyncua.server.uaprocessor import PublishRequestData, UaProcessor
    from asyncua.ua.ua_binary import struct_from_binary

    library = UaProcessor._process_message
    publish_id = ua.NodeId(ua.ObjectIds.PublishRequest_Encoding_DefaultBinary)

    async def publish(self: Any, requesthdr: Any, seqhdr: Any, body: Any, acks: list) -> bool:
        session = self.session
        rules = self._connection.security_policy.permissions
        if rules is not None and rules.check_validity(session.user, publish_id, body) is False:
            raise ua.uaerrors.BadUserAccessDenied
        self.session_last_activity = time.monotonic()
        session.touch()
        subscriptions, results = session.publish(acks)
        data = PublishRequestData(requesthdr=requesthdr, seqhdr=seqhdr, results=results)
        while self._publish_results_subs:  # a subscription waiting for a request: it takes this one
            subscription_id = next(iter(self._publish_results_subs))
            self._publish_results_subs.pop(subscription_id)
            sub = session.subscription_service.subscriptions.get(subscription_id)
            if sub is not None and await sub.publish_results(data):
                return True
        if len(self._publish_requests) >= self.publish_request_limit(subscriptions):
            self._evict_publish_request()
        self._publish_requests.append(data)
        return True

    async def process_decoded(self: Any, typeid: ua.NodeId, requesthdr: Any, seqhdr: Any, body: Any) -> bool:
        session = self.session
        if typeid != publish_id or session is None or not session.is_activated():
            return await library(self, typeid, requesthdr, seqhdr, body)
        acks = struct_from_binary(ua.PublishParameters, body).SubscriptionAcknowledgements
        return await publish(self, requesthdr, seqhdr, body, acks)

    UaProcessor._process_message = process_decoded  # type: ignore[method-assign]


_log = logging.getLogger(__name__)


class _Cycles:
    """The publishing cycles of every subscription with one publishing interval, on one task: it wakes once per
    interval and publishes each subscription in turn, as each one's own task did (asyncua gives every subscription a
    task that sleeps for the interval; with 20 clients at 100 ms that is 200 timer and task wake-ups a second, the
    largest single part of what a client cost). A subscription started joins at the next cycle and is published once
    at once, as before; one stopped or expired (its lifetime count reached) is left out from then on; one whose
    publish raises is logged and left out, as its task ended before."""

    def __init__(self, period_s: float, timers: dict[float, _Cycles]) -> None:
        self.period_s = period_s
        self.subscriptions: dict[Any, None] = {}  # in the order they started
        self._timers = timers
        self.starting: set[asyncio.Task] = set()  # first publishes under way
        self.task = asyncio.get_running_loop().create_task(self._run())

    async def _run(self) -> None:
        due = time.monotonic()
        try:
            while self.subscriptions:
                due += self.period_s
                await asyncio.sleep(max(due - time.monotonic(), 0))
                for sub in list(self.subscriptions):
                    await _publish(sub, self)
        except asyncio.CancelledError:
            pass
        finally:
            if self._timers.get(self.period_s) is self:
                del self._timers[self.period_s]

    def join(self, sub: Any) -> None:
        """Take ``sub`` into the cycles and publish it once now (once this step of the event loop is done, so after
        the CreateSubscription response, as its own task did)."""
        self.subscriptions[sub] = None
        sub._task = self
        first = asyncio.get_running_loop().create_task(_publish(sub, self))
        self.starting.add(first)
        first.add_done_callback(self.starting.discard)

    def leave(self, sub: Any) -> None:
        self.subscriptions.pop(sub, None)
        if not self.subscriptions:
            self.task.cancel()


async def _publish(sub: Any, cycles: _Cycles) -> None:
    if sub._task is not cycles or sub._closing:
        return
    try:
        await sub.publish_results()
    except Exception:
        _log.exception("Exception in subscription loop")
        cycles.leave(sub)
        sub._task = None
    if sub._task is not cycles:  # expired in that publish
        cycles.leave(sub)


_timers_by_loop: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Per event loop: publishing interval in seconds -> its :class:`_Cycles`."""


def _one_timer_per_interval(subscription: type) -> None:
    """Serve asyncua's subscriptions (``subscription``, its InternalSubscription) with one :class:`_Cycles` per
    publishing interval. A subscription's ``_task`` is its cycles while it is in them (the library tests it for
    "running" and clears it when the subscription expires)."""

    async def start(self: Any) -> None:
        if self.data.RevisedPublishingInterval <= 0.0:
            return
        self._closing = False
        timers = _timers_by_loop.setdefault(asyncio.get_running_loop(), {})
        period_s = self.data.RevisedPublishingInterval / 1000.0
        cycles = timers.get(period_s)
        if cycles is None or cycles.task.done() or cycles.task.cancelling():
            cycles = timers[period_s] = _Cycles(period_s, timers)
        cycles.join(self)

    async def stop(self: Any) -> None:
        cycles = self._task
        if cycles is not None:
            self._closing = True
            self._task = None
            cycles.leave(self)
        self.monitored_item_srv.delete_all_monitored_items()

    subscription.start = start
    subscription.stop = stop
