"""``aioadept send`` as a real process against a ScriptedServer over TCP."""

from __future__ import annotations

import asyncio
import json
import sys

import pytest

from aioadept.cli.send import main, parse_skill
from aioadept.commands import Skill
from aioadept.protocol import parse_command
from aioadept.testing import Reply, ScriptedServer


async def run_cli(*argv: str) -> tuple[int, str, str]:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "aioadept.cli", "send", *argv,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    out, err = await proc.communicate()
    return proc.returncode, out.decode(), err.decode()


@pytest.mark.timeout(20)
async def test_send_sequential_prints_one_line_per_ack():
    async with ScriptedServer() as server:
        code, out, err = await run_cli("--port", str(server.port), "move_to:300,0,500.5,0,180,0", "break",
                                       "set_speed:20")
    assert code == 0, err
    lines = out.splitlines()
    assert [line.split()[1:3] for line in lines] == [["move_to", "done"], ["break", "done"], ["set_speed", "done"]]
    # First the connect-time hello (is this a RobotServer?), in a write of its own; then the commands.
    assert parse_command(server.lines()[0]).skill == "hello"
    assert [parse_command(x).args for x in server.lines()[1:]] == [(300, 0, 500.5, 0, 180, 0), (), (20,)]
    assert "pose=300.000,0.000,500.000,0.000,180.000,0.000" in lines[0]
    assert len(server.connections[0].chunks) == 1 + 3  # sequential: one write per command


@pytest.mark.timeout(20)
async def test_send_joined_json_and_error_exit_status():
    async with ScriptedServer({"move_to": Reply.error(-610, "location out of range")}) as server:
        code, out, err = await run_cli("--port", str(server.port), "--joined", "--json", "set_speed:5",
                                       "move_to:9000,0,0,0,0,0")
    assert code == 1
    records = [json.loads(x) for x in out.splitlines()]
    assert [(r["skill"], r["status"]) for r in records] == [("set_speed", "done"), ("move_to", "error")]
    assert records[1]["extra"] == ["-610", "location out of range"]
    assert "location out of range" in err
    assert server.connections[0].chunks[1].count(b"\r\n") == 2  # joined: one write (after the hello's)


@pytest.mark.timeout(20)
async def test_send_connection_refused_exit_3():
    async with ScriptedServer() as server:
        port = server.port
    code, out, err = await run_cli("--port", str(port), "--connect-timeout", "2", "break")
    assert code == 3 and out == "" and "connect" in err


def test_parse_skill_and_usage_errors(capsys):
    assert parse_skill("move_to:1,-2.5,3,4,5,6") == Skill("move_to", 1, -2.5, 3, 4, 5, 6)
    assert parse_skill("break") == Skill("break")
    assert parse_skill("set_speed:20").calls()[0].args == (20,)
    assert main(["move_to:1,x"]) == 2
    assert "argument 1" in capsys.readouterr().err
    assert main(["Bad-Name"]) == 2
    assert "skill" in capsys.readouterr().err


@pytest.mark.timeout(20)
async def test_send_names_the_server_with_robot_as_every_client_does():
    async with ScriptedServer() as server:
        code, out, err = await run_cli("--robot", f"127.0.0.1:{server.port}", "here")
        both = await run_cli("--robot", f"127.0.0.1:{server.port}", "--port", str(server.port), "here")
    assert code == 0, err
    assert out.split()[1:3] == ["here", "done"]
    assert [parse_command(x).skill for x in server.lines()] == ["hello", "here"]  # the second run sent nothing
    code, out, err = both
    assert code == 2 and out == "" and len(err.splitlines()) == 1
    assert "--robot" in err and "--host/--port" in err


def test_send_robot_mistakes_are_one_line(capsys):
    with pytest.raises(SystemExit) as exited:
        main(["--robot", "127.0.0.1:99999", "here"])
    assert exited.value.code == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "--robot '127.0.0.1:99999'" in err
