"""``aioadept opcua --config CELL``: many robots of one cell file, one
MotionDevice each, their axes and MotionDeviceCategory from each robot's model; the server offering SecurityPolicy
None and Basic256Sha256 SignAndEncrypt, and an authenticated Stop over an encrypted session. Real processes on
127.0.0.1: a Viper s850 sim and a Cobra s600 sim, each publishing its state, one ``aioadept opcua`` following both,
asyncua's client."""

from __future__ import annotations

import importlib.util
import os
import signal

import pytest

from aioadept.commands import Here, MoveJoints, SetSpeed

from opcuacell import ROBOTICS_NS, opcua_cell_file
from test_opcua_server import Changes, child, find_system, until

pytestmark = pytest.mark.skipif(importlib.util.find_spec("asyncua") is None,
                                reason="the [opcua] extra (asyncua) is not installed")

DI = "http://opcfoundation.org/UA/DI/"
CELL = ('allow_commands = true\nusers = "users"\nsecurity = ["none", "sign-and-encrypt"]\n'
        'certificate = "server-cert.der"\nprivate_key = "server-key.pem"\n'
        '[opcua.devices.arm]\nserial_number = "V-0042"\ncontroller_model = "SmartController EX"\n')


async def devices(client, system) -> dict:
    from asyncua import ua

    rns = await client.get_namespace_index(ROBOTICS_NS)
    folder = await system.get_child([ua.QualifiedName("MotionDevices", rns)])
    return {(await d.read_browse_name()).Name: d for d in await folder.get_children()}


async def axes_of(client, device) -> list:
    """Each axis of ``device`` in order: (axis node, MotionProfile, ActualPosition node, its unit's id)."""
    from asyncua import ua

    folder = await child(client, device, (ROBOTICS_NS, "Axes"))
    out = []
    for axis in sorted(await folder.get_children(), key=lambda n: n.nodeid.to_string()):
        pos = await child(client, axis, (DI, "ParameterSet"), (ROBOTICS_NS, "ActualPosition"))
        eu = await (await pos.get_child([ua.QualifiedName("EngineeringUnits", 0)])).read_value()
        profile = await (await child(client, axis, (ROBOTICS_NS, "MotionProfile"))).read_value()
        out.append((axis, profile, pos, eu.UnitId))
    return out


@pytest.mark.timeout(90)
async def test_a_cell_file_of_a_viper_and_a_cobra_is_two_motion_devices_with_their_own_axes(tmp_path) -> None:
    from asyncua import Client

    from aioadept.client import RobotClient
    from aioadept.opcua.security import server_certificate

    users = tmp_path / "users"
    users.write_text("operator:s3cret\n")
    users.chmod(0o600)
    await server_certificate("127.0.0.1", tmp_path)  # server-cert.der, server-key.pem, as the cell file names them
    async with opcua_cell_file(tmp_path, {"arm": "viper-s850", "scara": "cobra-s600"}, CELL) as cell, \
            Client(cell.url) as client:
        system = await find_system(client)
        found = await devices(client, system)
        assert sorted(found) == ["arm", "scara"]
        arm, scara = await axes_of(client, found["arm"]), await axes_of(client, found["scara"])
        assert len(arm) == 6 and len(scara) == 4
        # A Cobra's J3 is the quill: LINEAR (3), in millimetres (UNECE MMT); the others ROTARY (1) in degrees (DD).
        assert [p for _, p, _, _ in scara] == [1, 1, 3, 1] and [p for _, p, _, _ in arm] == [1] * 6
        assert [u for *_, u in scara] == [0x4444, 0x4444, 0x4D4D54, 0x4444]
        assert (await scara[2][0].read_display_name()).Text == "joint_3"
        speed = await child(client, scara[2][0], (DI, "ParameterSet"), (ROBOTICS_NS, "ActualSpeed"))
        eu = await (await speed.get_child([_qn0("EngineeringUnits")])).read_value()
        assert eu.UnitId == 0x433136  # C16: millimetre per second

        async def text(device, *path):
            return (await (await child(client, device, *path)).read_data_value(raise_on_bad_status=False))

        category = {n: await (await child(client, d, (ROBOTICS_NS, "MotionDeviceCategory"))).read_value()
                    for n, d in found.items()}
        assert category == {"arm": 1, "scara": 2}  # ARTICULATED_ROBOT, SCARA_ROBOT: from each robot's model
        assert (await text(found["scara"], (DI, "Model"))).Value.Value.Text == "Cobra s600"
        assert (await text(found["arm"], (DI, "SerialNumber"))).Value.Value == "V-0042"  # the file's identity
        assert (await text(found["scara"], (DI, "SerialNumber"))).StatusCode.is_bad()    # nobody said it

        # Each robot's values are its own stream's: the Cobra's quill moves in mm, the Viper stays at home.
        changes = Changes()
        sub = await client.create_subscription(50, changes)
        await sub.subscribe_data_change([pos for _, _, pos, _ in scara + arm])
        target = [20.0, 70.0, 150.0, 10.0, 0.0, 0.0]
        async with RobotClient("127.0.0.1", int(cell.sims["scara"].ready["port"])) as robot:
            await robot.cmdexec(SetSpeed(100))
            await robot.cmdexec(MoveJoints(target))
        async with RobotClient("127.0.0.1", int(cell.sims["arm"].ready["port"])) as robot:
            home = [float(j) for j in (await robot.cmdexec(Here())).messages[0].ack.extra[0].split(",")]

        def at(axes, want) -> bool:
            vals = [changes.last.get(pos.nodeid) for _, _, pos, _ in axes]
            return all(v is not None and v.StatusCode.is_good() and abs(v.Value.Value - w) <= 0.01
                       for v, w in zip(vals, want, strict=True))

        await until(lambda: at(scara, target[:4]) and at(arm, home), 10, "each robot's own joints")

        # One robot's stream stalls (its sim stopped): its values turn Uncertain within a second, the other robot's
        # stay Good; Good again when it resumes.
        def quality(axes, good: bool) -> bool:
            return all(changes.last[pos.nodeid].StatusCode.is_good() == good for _, _, pos, _ in axes)

        os.kill(cell.sims["scara"].proc.pid, signal.SIGSTOP)
        try:
            waited = await until(lambda: quality(scara, False), 3, "the stalled Cobra's values not Good")
            assert waited < 1.0, waited
            assert all(changes.last[pos.nodeid].StatusCode.is_uncertain() for _, _, pos, _ in scara)
            assert quality(arm, True)
        finally:
            os.kill(cell.sims["scara"].proc.pid, signal.SIGCONT)
        await until(lambda: quality(scara, True) and quality(arm, True), 5, "Good values once the Cobra resumes")
        await stop_over_an_encrypted_session(tmp_path, cell, scara[0][2])


async def stop_over_an_encrypted_session(tmp_path, cell, position) -> None:
    """The endpoints offered are None and Basic256Sha256 SignAndEncrypt; a client with its own certificate and a user
    of the users file stops the Cobra during a motion over SignAndEncrypt: acked ``done``, and the arm rests. The
    user may not write a value either (``position``, a live variable): BadNotWritable."""
    import asyncio
    import time

    from asyncua import Client, ua
    from asyncua.crypto.cert_gen import setup_self_signed_certificate
    from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256
    from cryptography.x509.oid import ExtendedKeyUsageOID

    from aioadept.client import RobotClient
    from aioadept.errors import CommandAborted

    async with Client(cell.url) as anonymous:
        offered = {(e.SecurityPolicyUri.rsplit("#", 1)[-1], e.SecurityMode) for e in await anonymous.get_endpoints()}
    assert offered == {("None", ua.MessageSecurityMode.None_),
                       ("Basic256Sha256", ua.MessageSecurityMode.SignAndEncrypt)}, offered
    uri = "urn:aioadept:test:client"
    key, cert = tmp_path / "client-key.pem", tmp_path / "client-cert.der"
    await setup_self_signed_certificate(key, cert, uri, "localhost", [ExtendedKeyUsageOID.CLIENT_AUTH],
                                        {"commonName": "test client"})
    client = Client(cell.url)
    client.application_uri = uri
    await client.set_security(SecurityPolicyBasic256Sha256, str(cert), str(key),
                              mode=ua.MessageSecurityMode.SignAndEncrypt)
    client.set_user("operator")
    client.set_password("s3cret")
    port = int(cell.sims["scara"].ready["port"])
    async with client, RobotClient("127.0.0.1", port) as robot, RobotClient("127.0.0.1", port) as watcher:
        assert client.security_policy.Mode == ua.MessageSecurityMode.SignAndEncrypt
        found = await devices(client, await find_system(client))
        vidx = await client.get_namespace_index("urn:aioadept:opcua:commands")
        stop = await found["scara"].get_child([ua.QualifiedName("Stop", vidx)])
        with pytest.raises(ua.UaStatusCodeError) as refused:
            await client.get_node(position.nodeid).write_value(ua.DataValue(ua.Variant(1.0, ua.VariantType.Double)))
        assert refused.value.code == ua.StatusCodes.BadNotWritable
        await robot.cmdexec(SetSpeed(10))
        motion = asyncio.create_task(robot.cmdexec(MoveJoints([-20.0, 100.0, 120.0, -10.0, 0.0, 0.0])))
        t_end = time.monotonic() + 5
        while not (await watcher.status()).moving:
            assert time.monotonic() < t_end, "the motion did not start"
            await asyncio.sleep(0.02)
        ack = await found["scara"].call_method(stop)
        assert ":done:" in ack, ack
        with pytest.raises(CommandAborted):
            await motion
        rest = await watcher.here()
        await asyncio.sleep(0.3)
        assert not (await watcher.status()).moving and await watcher.here() == rest


def _qn0(name: str):
    from asyncua import ua

    return ua.QualifiedName(name, 0)
