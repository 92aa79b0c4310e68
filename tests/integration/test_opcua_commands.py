"""``aioadept opcua --allow-commands``: Stop and RunSkill from OPC UA, for authenticated users
only, through the server's own RobotClient. Real processes (``aioadept sim``, ``aioadept opcua``) on 127.0.0.1 and
asyncua's client: an anonymous call is refused (BadUserAccessDenied), a wrong password is not a session, an
authenticated Stop during a motion is acked ``done`` and the arm rests (the motion's own client sees it aborted),
RunSkill sends one command and answers its ack line; a write to a variable is refused (BadNotWritable)."""

from __future__ import annotations

import asyncio
import importlib.util
import time

import pytest

from aioadept.commands import Break, MoveJoints, SetSpeed

from opcuacell import TARGET, opcua_cell
from test_opcua_server import axis_variables, find_system

pytestmark = pytest.mark.skipif(importlib.util.find_spec("asyncua") is None,
                                reason="the [opcua] extra (asyncua) is not installed")

VENDOR_NS = "urn:aioadept:opcua:commands"


async def robot_and_methods(client):
    from asyncua import ua

    system = await find_system(client)
    rns = await client.get_namespace_index("http://opcfoundation.org/UA/Robotics/")
    vidx = await client.get_namespace_index(VENDOR_NS)
    (device,) = await (await system.get_child([ua.QualifiedName("MotionDevices", rns)])).get_children()
    return (device, await device.get_child([ua.QualifiedName("Stop", vidx)]),
            await device.get_child([ua.QualifiedName("RunSkill", vidx)]))


def user_client(url: str, name: str, password: str):
    from asyncua import Client

    client = Client(url)
    client.set_user(name)
    client.set_password(password)
    return client


@pytest.mark.timeout(90)
async def test_only_an_authenticated_user_stops_the_robot_and_the_arm_rests(tmp_path) -> None:
    from asyncua import Client, ua

    from aioadept.client import RobotClient
    from aioadept.errors import CommandAborted

    users = tmp_path / "users"
    users.write_text("# who may command the cell\noperator:s3cret word\n")
    users.chmod(0o600)
    async with opcua_cell(tmp_path, "--allow-commands", "--users", str(users)) as cell:
        async with Client(cell.url) as anonymous:
            device, stop, run_skill = await robot_and_methods(anonymous)
            with pytest.raises(ua.UaStatusCodeError) as refused:
                await device.call_method(stop)
            assert refused.value.code == ua.StatusCodes.BadUserAccessDenied
            with pytest.raises(ua.UaStatusCodeError) as refused:
                await device.call_method(run_skill, ua.Variant("here", ua.VariantType.String),
                                         ua.Variant([], ua.VariantType.Double))
            assert refused.value.code == ua.StatusCodes.BadUserAccessDenied
            position = (await axis_variables(anonymous, await find_system(anonymous), "ActualPosition"))[0]
            with pytest.raises(ua.UaStatusCodeError) as refused:
                await position.write_value(ua.DataValue(ua.Variant(1.0, ua.VariantType.Double)))
            assert refused.value.code == ua.StatusCodes.BadNotWritable
        with pytest.raises(Exception) as wrong:   # no session for a wrong password
            async with user_client(cell.url, "operator", "guess"):
                pass
        assert "BadUserAccessDenied" in repr(wrong.value) or "BadIdentityTokenRejected" in repr(wrong.value), \
            repr(wrong.value)

        async with user_client(cell.url, "operator", "s3cret word") as client, \
                RobotClient("127.0.0.1", cell.robot_port) as robot, \
                RobotClient("127.0.0.1", cell.robot_port) as watcher:
            device, stop, run_skill = await robot_and_methods(client)
            await robot.cmdexec(SetSpeed(10))
            motion = asyncio.create_task(robot.cmdexec(MoveJoints(TARGET)))
            t_end = time.monotonic() + 5
            while not (await watcher.status()).moving:
                assert time.monotonic() < t_end, "the motion did not start"
                await asyncio.sleep(0.02)
            ack = await device.call_method(stop)
            assert ":done:" in ack, ack
            with pytest.raises(CommandAborted):
                await motion
            assert not (await watcher.status()).moving
            rest = await watcher.here()
            await asyncio.sleep(0.3)
            assert await watcher.here() == rest   # at rest: nothing moves it after the acked stop
            assert ack.split(":")[3].split(",")[:3] == [f"{v:.3f}" for v in (rest.x, rest.y, rest.z)]

            here = await device.call_method(run_skill, ua.Variant("here", ua.VariantType.String),
                                            ua.Variant([], ua.VariantType.Double))
            assert ":done:" in here and len(here.split(":")[-1].split(",")) == 6, here  # here's joints
            with pytest.raises(ua.UaStatusCodeError) as refused:
                await device.call_method(run_skill, ua.Variant("Not A Skill", ua.VariantType.String),
                                         ua.Variant([], ua.VariantType.Double))
            assert refused.value.code == ua.StatusCodes.BadInvalidArgument

            def joints(line: str) -> list[float]:
                return [float(j) for j in line.split(":")[-1].split(",")]

            moved = await device.call_method(run_skill, ua.Variant("move_rel_joints", ua.VariantType.String),
                                             ua.Variant([5.0, 0, 0, 0, 0, 0], ua.VariantType.Double))
            assert ":done:" in moved, moved
            await robot.cmdexec(Break())
            after = await device.call_method(run_skill, ua.Variant("here", ua.VariantType.String),
                                             ua.Variant([], ua.VariantType.Double))
            # Sent once: the first joint moved by 5 degrees, not 10, and nothing else moved.
            assert [round(a - b, 2) for a, b in zip(joints(after), joints(here), strict=True)] == [5.0, 0, 0, 0, 0, 0]


@pytest.mark.timeout(60)
async def test_without_allow_commands_there_are_no_methods(tmp_path) -> None:
    from asyncua import Client, ua

    async with opcua_cell(tmp_path) as cell, Client(cell.url) as client:
        system = await find_system(client)
        rns = await client.get_namespace_index("http://opcfoundation.org/UA/Robotics/")
        (device,) = await (await system.get_child([ua.QualifiedName("MotionDevices", rns)])).get_children()
        assert await device.get_methods() == []
        assert VENDOR_NS not in await client.get_namespace_array()


@pytest.mark.parametrize("args, says", [
    (["--allow-commands"], "--allow-commands needs --users FILE"),
    (["--users", "users.txt"], "--users is only for --allow-commands"),
    (["--allow-commands", "--users", "no-such-file"], "no-such-file"),
])
def test_commands_without_users_are_refused_in_one_line(args: list[str], says: str) -> None:
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "aioadept", "opcua", *args], capture_output=True, text=True,
                          timeout=30)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("aioadept opcua: ") and says in lines[0], proc.stderr
