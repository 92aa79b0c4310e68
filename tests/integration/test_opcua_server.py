"""``aioadept opcua``: what a plant's OPC UA client sees of a robot, checked with asyncua's client
against real processes (``aioadept sim`` publishing its state, ``aioadept opcua`` following it, 127.0.0.1).

The client finds the MotionDeviceSystem by its type definition in the Robotics namespace (no node id known before),
subscribes to the six ActualPosition values while the sim moves and sees them match ``here``'s joints at rest;
every instantiated node is walked against its type's declarations in the nodesets (every Mandatory child present,
with the declared data type or type definition); a stalled stream (the sim stopped by SIGSTOP) turns the values
Uncertain within a second, and Good again when it resumes; the robot server restarting does the same; clients killed
while subscribed leave the others served, and SIGTERM with clients subscribed during a motion stops the server at
once.
"""

from __future__ import annotations

import asyncio
import importlib.util
import os
import signal
import time

import pytest

from aioadept.commands import Here, MoveJoints, SetSpeed

from opcuacell import ROBOTICS_NS, TARGET, opcua_cell

pytestmark = pytest.mark.skipif(importlib.util.find_spec("asyncua") is None,
                                reason="the [opcua] extra (asyncua) is not installed")


async def find_system(client):
    """The node under Objects whose type definition is Robotics' MotionDeviceSystemType, found by browsing."""
    from asyncua import ua

    rns = await client.get_namespace_index(ROBOTICS_NS)
    seen, todo = set(), [client.nodes.objects]
    while todo:
        node = todo.pop(0)
        for ref in await node.get_references(refs=ua.ObjectIds.HierarchicalReferences,
                                             direction=ua.BrowseDirection.Forward, nodeclassmask=ua.NodeClass.Object):
            if ref.NodeId in seen:
                continue
            seen.add(ref.NodeId)
            td = ref.TypeDefinition
            if td.NamespaceIndex == rns and (await client.get_node(td).read_browse_name()).Name == \
                    "MotionDeviceSystemType":
                return client.get_node(ref.NodeId)
            if ref.NodeId.NamespaceIndex != 0:  # the standard's own objects hold no MotionDeviceSystem
                todo.append(client.get_node(ref.NodeId))
    raise AssertionError("no MotionDeviceSystemType instance under Objects")


async def child(client, node, *names: tuple[str, str]):
    from asyncua import ua

    path = [ua.QualifiedName(name, await client.get_namespace_index(uri)) for uri, name in names]
    return await node.get_child(path)


async def axis_variables(client, system, name: str):
    from asyncua import ua

    rns = await client.get_namespace_index(ROBOTICS_NS)
    di = "http://opcfoundation.org/UA/DI/"
    devices = await system.get_child([ua.QualifiedName("MotionDevices", rns)])
    (device,) = await devices.get_children()
    axes = await child(client, device, (ROBOTICS_NS, "Axes"))
    out = []
    for axis in sorted(await axes.get_children(), key=lambda n: n.nodeid.to_string()):
        out.append(await child(client, axis, (di, "ParameterSet"), (ROBOTICS_NS, name)))
    return out


class Changes:
    """asyncua's subscription handler: every data change, by node."""

    def __init__(self) -> None:
        self.last: dict = {}
        self.count = 0

    def datachange_notification(self, node, val, data) -> None:
        self.last[node.nodeid] = data.monitored_item.Value
        self.count += 1


async def until(pred, timeout_s: float, what: str) -> float:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        if pred():
            return time.monotonic() - t0
        await asyncio.sleep(0.02)
    raise AssertionError(f"{what} not within {timeout_s} s")


@pytest.mark.timeout(60)
async def test_a_client_finds_the_robot_by_type_and_sees_here_s_joints_at_rest(tmp_path) -> None:
    from asyncua import Client, ua

    from aioadept.client import RobotClient

    async with opcua_cell(tmp_path) as cell, Client(cell.url) as client:
        system = await find_system(client)
        positions = await axis_variables(client, system, "ActualPosition")
        assert len(positions) == 6
        eu = await (await positions[0].get_child([ua.QualifiedName("EngineeringUnits", 0)])).read_value()
        assert (eu.UnitId, eu.DisplayName.Text) == (0x4444, "°")  # UNECE "DD": degree
        changes = Changes()
        sub = await client.create_subscription(50, changes)
        await sub.subscribe_data_change(positions)
        async with RobotClient("127.0.0.1", cell.robot_port) as robot:
            await robot.cmdexec(SetSpeed(100))
            await robot.cmdexec(MoveJoints(TARGET))  # with its break: acked at rest
            here = [float(j) for j in (await robot.cmdexec(Here())).messages[0].ack.extra[0].split(",")]
        assert max(abs(a - b) for a, b in zip(here, TARGET, strict=True)) < 0.01

        def at_rest() -> bool:
            vals = [changes.last.get(n.nodeid) for n in positions]
            return all(v is not None and v.StatusCode.is_good() and abs(v.Value.Value - h) <= 0.01
                       for v, h in zip(vals, here, strict=True))

        await until(at_rest, 5, "the six ActualPosition at here's joints")
        # Values came while it moved, not only at the end, each with the robot's own time as source timestamp.
        assert changes.count > 12
        stamps = [changes.last[n.nodeid].SourceTimestamp.timestamp() for n in positions]
        assert all(abs(s - time.time()) < 30 for s in stamps)
        rns = await client.get_namespace_index(ROBOTICS_NS)
        di = "http://opcfoundation.org/UA/DI/"
        safety = await system.get_child([ua.QualifiedName("SafetyStates", rns)])
        (state,) = await safety.get_children()
        estop = await (await child(client, state, (di, "ParameterSet"), (ROBOTICS_NS, "EmergencyStop"))
                       ).read_data_value(raise_on_bad_status=False)
        mode = await (await child(client, state, (di, "ParameterSet"), (ROBOTICS_NS, "OperationalMode"))
                      ).read_data_value(raise_on_bad_status=False)
        assert estop.StatusCode.is_good() and estop.Value.Value is False  # the sim's status: es=0
        # V+ does not say the operating mode: Bad, and no value made up.
        assert mode.StatusCode.is_bad() and mode.Value.Value is None
        # The identity the cell gave (opcuacell: --model, --category), and what nobody gave: Bad, no value.
        (device,) = await (await system.get_child([ua.QualifiedName("MotionDevices", rns)])).get_children()
        model = await (await child(client, device, (di, "Model"))).read_data_value(raise_on_bad_status=False)
        category = await (await child(client, device, (ROBOTICS_NS, "MotionDeviceCategory"))).read_value()
        serial = await (await child(client, device, (di, "SerialNumber"))).read_data_value(raise_on_bad_status=False)
        assert model.StatusCode.is_good() and model.Value.Value.Text == "Viper s850"
        assert category == 1  # ARTICULATED_ROBOT
        assert serial.StatusCode.value == ua.StatusCodes.BadNotSupported and serial.Value.Value is None


@pytest.mark.timeout(60)
async def test_a_stalled_state_stream_turns_the_values_uncertain_within_a_second_and_back(tmp_path) -> None:
    from asyncua import Client, ua

    async with opcua_cell(tmp_path) as cell, Client(cell.url) as client:
        system = await find_system(client)
        positions = await axis_variables(client, system, "ActualPosition")
        changes = Changes()
        sub = await client.create_subscription(50, changes)
        await sub.subscribe_data_change(positions, attr=ua.AttributeIds.Value)
        await until(lambda: all(changes.last.get(n.nodeid) and changes.last[n.nodeid].StatusCode.is_good()
                                for n in positions), 5, "Good values")
        os.kill(cell.sim.proc.pid, signal.SIGSTOP)
        try:
            waited = await until(lambda: all(changes.last[n.nodeid].StatusCode.is_uncertain() for n in positions),
                                 3, "Uncertain values after the stream stalled")
            assert waited < 1.0, waited
            v = changes.last[positions[1].nodeid]
            assert v.StatusCode.value == ua.StatusCodes.UncertainNoCommunicationLastUsableValue
            assert v.Value.Value == pytest.approx(-90.0, abs=0.01)  # the last value it had, kept
        finally:
            os.kill(cell.sim.proc.pid, signal.SIGCONT)
        await until(lambda: all(changes.last[n.nodeid].StatusCode.is_good() for n in positions), 3,
                    "Good values once the stream is back")


async def _declarations(client, type_node, cache: dict) -> list:
    """The Mandatory and MandatoryPlaceholder children a node of ``type_node`` must have: from the type and each
    supertype (a type), or from the instance declaration itself; each (browse name, rule, node class, data type
    or type definition, the declaration node)."""
    from asyncua import ua

    if type_node.nodeid in cache:
        return cache[type_node.nodeid]
    sources = [type_node]
    if await type_node.read_node_class() in (ua.NodeClass.ObjectType, ua.NodeClass.VariableType):
        node = type_node
        while True:
            parents = await node.get_references(refs=ua.ObjectIds.HasSubtype, direction=ua.BrowseDirection.Inverse)
            if not parents:
                break
            node = client.get_node(parents[0].NodeId)
            sources.append(node)
    out, names = [], set()
    for src in sources:
        for ref in await src.get_references(refs=ua.ObjectIds.HierarchicalReferences,
                                            direction=ua.BrowseDirection.Forward):
            key = (ref.BrowseName.NamespaceIndex, ref.BrowseName.Name)
            if key in names:  # the most derived declaration of a name wins
                continue
            names.add(key)
            decl = client.get_node(ref.NodeId)
            rules = await decl.get_referenced_nodes(refs=ua.ObjectIds.HasModellingRule)
            rule = rules[0].nodeid.Identifier if rules else None
            if rule not in (ua.ObjectIds.ModellingRule_Mandatory, ua.ObjectIds.ModellingRule_MandatoryPlaceholder):
                continue
            kind = await decl.read_data_type() if ref.NodeClass == ua.NodeClass.Variable else ref.TypeDefinition
            out.append((ref.BrowseName, rule, ref.NodeClass, kind, decl))
    cache[type_node.nodeid] = out
    return out


async def _is_subtype(client, sub, sup, ref_type) -> bool:
    from asyncua import ua

    node = sub
    while True:
        if node == sup:
            return True
        parents = await client.get_node(node).get_references(refs=ref_type, direction=ua.BrowseDirection.Inverse)
        if not parents:
            return False
        node = parents[0].NodeId


@pytest.mark.timeout(120)
async def test_every_instantiated_node_has_every_mandatory_child_its_type_declares(tmp_path) -> None:
    from asyncua import Client, ua

    async with opcua_cell(tmp_path) as cell, Client(cell.url, timeout=30) as client:
        system = await find_system(client)
        cache: dict = {}
        problems: list[str] = []
        checked = 0

        async def check(node, against, path: str) -> None:
            nonlocal checked
            refs = await node.get_references(refs=ua.ObjectIds.HierarchicalReferences,
                                             direction=ua.BrowseDirection.Forward)
            for name, rule, nclass, kind, decl in await _declarations(client, against, cache):
                if rule == ua.ObjectIds.ModellingRule_MandatoryPlaceholder:
                    ok = [r for r in refs if r.NodeClass == nclass and await _is_subtype(
                        client, r.TypeDefinition, kind, ua.ObjectIds.HasSubtype)]
                    if not ok:
                        problems.append(f"{path}: no instance of placeholder {name.to_string()}")
                    continue
                found = [r for r in refs if r.BrowseName == name]
                if not found:
                    problems.append(f"{path}: Mandatory {name.to_string()} missing")
                    continue
                inst = client.get_node(found[0].NodeId)
                checked += 1
                if nclass == ua.NodeClass.Variable:
                    if not await _is_subtype(client, await inst.read_data_type(), kind, ua.ObjectIds.HasSubtype):
                        problems.append(f"{path}/{name.Name}: data type is not {kind.to_string()}")
                elif nclass == ua.NodeClass.Object and not await _is_subtype(
                        client, found[0].TypeDefinition, kind, ua.ObjectIds.HasSubtype):
                    problems.append(f"{path}/{name.Name}: type is not {kind.to_string()}")
                await check(inst, decl, f"{path}/{name.Name}")

        # Every object under the system (the placeholders' instances included) against its own type definition.
        seen, todo = set(), [(system, "MotionDeviceSystem")]
        while todo:
            node, path = todo.pop()
            if node.nodeid in seen:
                continue
            seen.add(node.nodeid)
            await check(node, client.get_node(await node.read_type_definition()), path)
            for ref in await node.get_references(refs=ua.ObjectIds.HierarchicalReferences,
                                                 direction=ua.BrowseDirection.Forward,
                                                 nodeclassmask=ua.NodeClass.Object):
                todo.append((client.get_node(ref.NodeId), f"{path}/{ref.BrowseName.Name}"))
        assert not problems, "\n".join(problems)
        # The system, its robot, 6 axes, 6 power trains with a motor each, a controller with its software and
        # task, a safety state: every one of them walked.
        assert len(seen) >= 1 + 1 + 6 + 12 + 3 + 1, len(seen)
        assert checked >= 90, checked


@pytest.mark.parametrize("endpoint, says", [
    ("opc.tcp://0.0.0.0:4840", "0.0.0.0 is not loopback, and nothing authenticates who connects there"),
    ("opc.tcp://192.0.2.7:4840", "192.0.2.7 is not loopback"),
    ("http://127.0.0.1:4840", "expected opc.tcp://HOST:PORT"),
    ("opc.tcp://127.0.0.1", "expected opc.tcp://HOST:PORT"),
])
def test_a_non_loopback_or_malformed_endpoint_is_refused_in_one_line(endpoint: str, says: str) -> None:
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "aioadept", "opcua", "--endpoint", endpoint], capture_output=True,
                          text=True, timeout=30)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("aioadept opcua: ") and says in lines[0], proc.stderr
    assert endpoint in lines[0]


def test_an_endpoint_already_in_use_is_one_line_and_exit_1() -> None:
    import socket
    import subprocess
    import sys

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc = subprocess.run([sys.executable, "-m", "aioadept", "opcua", "--endpoint", f"opc.tcp://127.0.0.1:{port}",
                               "--robot", "127.0.0.1:9", "--state-endpoint", "tcp://127.0.0.1:9"],
                              capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("aioadept opcua: ") and "address already in use" in lines[0]


VANISHING_CLIENT = """
import asyncio, sys
from asyncua import Client
class H:
    def datachange_notification(self, node, val, data):
        pass
async def main():
    client = Client(sys.argv[1])
    await client.connect()
    sub = await client.create_subscription(50, H())
    await sub.subscribe_data_change([client.get_node(n) for n in sys.argv[2:]])
    print("SUBSCRIBED", flush=True)
    await asyncio.sleep(3600)
asyncio.run(main())
"""


STOP_GRACE_S = 5.0
"""What a supervisor (aioadept.apps.processes.NodeProcess, docs/topology.md) gives a node after each signal."""


@pytest.mark.timeout(90)
async def test_a_client_that_vanishes_leaves_the_others_served_and_sigterm_under_load_exits_0_in_one_line(
        tmp_path) -> None:
    import sys

    from asyncua import Client

    from aioadept.client import RobotClient

    async with opcua_cell(tmp_path) as cell, Client(cell.url) as client:
        positions = await axis_variables(client, await find_system(client), "ActualPosition")
        gone = []
        for _ in range(3):  # three clients subscribed to the six positions, killed without a word (SIGKILL)
            proc = await asyncio.create_subprocess_exec(
                sys.executable, "-c", VANISHING_CLIENT, cell.url, *[n.nodeid.to_string() for n in positions],
                stdout=asyncio.subprocess.PIPE)
            assert proc.stdout is not None
            assert await asyncio.wait_for(proc.stdout.readline(), 30) == b"SUBSCRIBED\n"
            gone.append(proc)
        async with RobotClient("127.0.0.1", cell.robot_port) as robot:
            await robot.cmdexec(SetSpeed(100))
            move = asyncio.create_task(robot.cmdexec(MoveJoints(TARGET)))
            await asyncio.sleep(0.2)
            for proc in gone:
                proc.kill()
                await proc.wait()
            await move
        changes = Changes()
        sub = await client.create_subscription(50, changes)
        await sub.subscribe_data_change(positions)
        await until(lambda: all(changes.last.get(n.nodeid) and abs(changes.last[n.nodeid].Value.Value - t) <= 0.01
                                for n, t in zip(positions, TARGET, strict=True)), 10, "the target, to a client that stayed")
        async with RobotClient("127.0.0.1", cell.robot_port) as robot:
            await robot.cmdexec(MoveJoints([0.0, -90.0, 180.0, 0.0, 90.0, 0.0]))
        await until(lambda: abs(changes.last[positions[0].nodeid].Value.Value) <= 0.01, 10, "home again")
        assert cell.opcua.returncode is None  # still serving
        await _sigterm_under_load(cell, client, positions)


async def _sigterm_under_load(cell, client, positions) -> None:
    """SIGTERM during a motion, with ``client`` and three more subscribed at 100 ms, one of them no longer reading
    (its process busy, or gone without a word): the server exits 0 within a supervisor's grace, its last words one
    line that names the connections it closed."""
    import contextlib

    from asyncua import Client

    from aioadept.client import RobotClient

    more = []
    try:
        for _ in range(3):
            other = Client(cell.url, timeout=10)
            await other.connect()
            more.append(other)
            sub = await other.create_subscription(100, Changes())
            await sub.subscribe_data_change([other.get_node(n.nodeid) for n in positions])
        more[-1].uaclient.protocol.transport.pause_reading()
        async with RobotClient("127.0.0.1", cell.robot_port) as robot:
            await robot.cmdexec(SetSpeed(5))
            move = asyncio.create_task(robot.cmdexec(MoveJoints(TARGET)))
            await asyncio.sleep(0.3)  # under way: every client's values changing
            proc = cell.opcua.proc
            os.kill(proc.pid, signal.SIGTERM)
            code = await asyncio.wait_for(proc.wait(), STOP_GRACE_S)
            await robot.stop()
            await asyncio.gather(move, return_exceptions=True)
    finally:
        for other in more:  # the server is gone: whatever a client says on its way out, it is closed
            with contextlib.suppress(Exception):
                await asyncio.wait_for(other.disconnect(), 0.5)
    assert code == 0
    await until(lambda: "stopped in" in cell.opcua.tail(), 5, "the server's last line")
    said = [line for line in cell.opcua.tail().splitlines() if "aioadept opcua:" in line]
    assert len(said) == 1 and said[0].endswith(" 4 client connection(s) closed"), cell.opcua.tail()
    assert "Traceback" not in cell.opcua.tail()


@pytest.mark.timeout(120)
async def test_the_robot_server_restarting_turns_values_uncertain_and_back_to_good(tmp_path) -> None:
    from asyncua import Client, ua

    from aioadept.ports import free_port
    from aioadept.testing.nodes import running_node

    port, state = free_port(), f"tcp://127.0.0.1:{free_port()}"
    sim_args = ("--port", str(port), "--stop-port", "none", "--state-rate", "50", "--state-endpoint", state)
    url = f"opc.tcp://127.0.0.1:{free_port()}"
    sim = running_node("sim", *sim_args, log_path=tmp_path / "sim1.log")
    await sim.__aenter__()
    try:
        async with running_node("opcua", "--robot", f"127.0.0.1:{port}", "--state-endpoint", state, "--endpoint",
                                url, log_path=tmp_path / "opcua.log", ready_timeout_s=60), Client(url) as client:
            system = await find_system(client)
            position = (await axis_variables(client, system, "ActualPosition"))[1]
            rns = await client.get_namespace_index(ROBOTICS_NS)
            (state_obj,) = await (await system.get_child([ua.QualifiedName("SafetyStates", rns)])).get_children()
            estop = await child(client, state_obj, ("http://opcfoundation.org/UA/DI/", "ParameterSet"),
                                (ROBOTICS_NS, "EmergencyStop"))
            changes = Changes()
            sub = await client.create_subscription(50, changes)
            await sub.subscribe_data_change([position, estop])

            def status(node):
                v = changes.last.get(node.nodeid)
                return v.StatusCode if v is not None else None

            await until(lambda: status(position) and status(position).is_good() and status(estop)
                        and status(estop).is_good(), 10, "Good values")
            await sim.__aexit__(None, None, None)  # the robot server goes away (SIGINT, a clean exit)
            sim = None
            await until(lambda: status(position).is_uncertain() and status(estop).is_uncertain(), 5,
                        "Uncertain values while the robot server is away")
            sim = running_node("sim", *sim_args, log_path=tmp_path / "sim2.log")
            await sim.__aenter__()
            await until(lambda: status(position).is_good() and status(estop).is_good(), 15,
                        "Good values once the robot server is back")
    finally:
        if sim is not None:
            await sim.__aexit__(None, None, None)
