"""Who may command the robot over the network is said loudly.

Every command that listens refuses, before it binds, an address beyond loopback that authenticates nobody, in one
line naming the option and the address and saying ``--insecure``; the bridge says at every start who may command
the robot. Nothing here binds beyond loopback: the port given with ``0.0.0.0`` is held on 127.0.0.1 by the test,
so a command that skipped the check would fail to bind (EADDRINUSE) instead of exposing anything. The refusals run
one case of each table as a real ``python -m aioadept`` process and the others in this process
(tests/integration/cliinproc.py), the same assertions on the exit status and the line.
"""

from __future__ import annotations

import importlib.util
import socket
from contextlib import contextmanager

import pytest

from aioadept.cli.options import Listener, check_listeners, is_loopback

from bustransports import start_zenoh_router
from cliinproc import run_inproc, run_real

zenoh_needed = pytest.mark.skipif(importlib.util.find_spec("zenoh") is None,
                                  reason="the [zenoh] extra (eclipse-zenoh) is not installed")


@contextmanager
def held_port():
    """A port held on 127.0.0.1 (listening): binding 0.0.0.0 on it fails, so nothing is ever exposed."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield s.getsockname()[1]


CASES = [
    ("sim", ["--host", "0.0.0.0", "--port", "{p}", "--stop-port", "none"], "--host '0.0.0.0'"),
    ("sim", ["--port", "0", "--state-endpoint", "tcp://0.0.0.0:{p}"], "--state-endpoint 'tcp://0.0.0.0:{p}'"),
    ("state", ["--robot", "127.0.0.1:1", "--state-endpoint", "tcp://0.0.0.0:{p}"],
     "--state-endpoint 'tcp://0.0.0.0:{p}'"),
    ("vision", ["--response-endpoint", "@tcp://0.0.0.0:{p}", "--request-endpoint", "@tcp://127.0.0.1:0"],
     "--response-endpoint '@tcp://0.0.0.0:{p}'"),
    ("vision", ["--request-endpoint", "@tcp://0.0.0.0:{p}", "--response-endpoint", "@tcp://127.0.0.1:0"],
     "--request-endpoint '@tcp://0.0.0.0:{p}'"),
    ("focus", ["--response-endpoint", "@tcp://0.0.0.0:{p}", "--robot", "127.0.0.1:1"],
     "--response-endpoint '@tcp://0.0.0.0:{p}'"),
]
ZENOH_CASES = [
    ("bridge", ["--robot", "127.0.0.1:1", "--zenoh-listen", "tcp/0.0.0.0:{p}"], "--zenoh-listen 'tcp/0.0.0.0:{p}'"),
    ("ros2", ["--zenoh-listen", "tcp/0.0.0.0:{p}"], "--zenoh-listen 'tcp/0.0.0.0:{p}'"),
    ("sim", ["--port", "0", "--state-endpoint", "none", "--transport", "zenoh", "--zenoh-listen", "tcp/0.0.0.0:{p}"],
     "--zenoh-listen 'tcp/0.0.0.0:{p}'"),
    ("state", ["--robot", "127.0.0.1:1", "--transport", "zenoh", "--zenoh-listen", "tcp/0.0.0.0:{p}"],
     "--zenoh-listen 'tcp/0.0.0.0:{p}'"),
    ("vision", ["--transport", "zenoh", "--zenoh-listen", "tcp/0.0.0.0:{p}"], "--zenoh-listen 'tcp/0.0.0.0:{p}'"),
]


def _refused(command: str, argv: list[str], said: str, *, real: bool) -> None:
    with held_port() as p:
        out = (run_real if real else run_inproc)(command, *(a.format(p=p) for a in argv))
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 2, out.stderr
    assert len(lines) == 1 and "Traceback" not in out.stderr, out.stderr
    assert lines[0].startswith(f"aioadept {command}: ") and said.format(p=p) in lines[0], lines[0]
    assert "not loopback" in lines[0] and "pass --insecure to accept it" in lines[0], lines[0]


@pytest.mark.timeout(60)
@pytest.mark.parametrize(("command", "argv", "said"), CASES, ids=[f"{c[0]}-{c[2].split()[0]}" for c in CASES])
def test_a_listener_beyond_loopback_without_authentication_is_refused_in_one_line(command, argv, said):
    _refused(command, argv, said, real=said == "--host '0.0.0.0'")


@zenoh_needed
@pytest.mark.timeout(60)
@pytest.mark.parametrize(("command", "argv", "said"), ZENOH_CASES, ids=[c[0] for c in ZENOH_CASES])
def test_a_zenoh_router_beyond_loopback_without_credentials_is_refused_in_one_line(command, argv, said):
    _refused(command, argv, said, real=command == "bridge")


@pytest.mark.parametrize("command", ["sim", "state", "vision", "bridge", "ros2", "focus"])
def test_every_listening_command_takes_insecure(command):
    import importlib

    parser = importlib.import_module(f"aioadept.cli.{command}").build_parser()
    assert parser.parse_args(["--insecure"]).insecure is True
    assert parser.parse_args([]).insecure is False


def test_insecure_accepts_the_exposed_listeners_with_one_warning_line(capsys):
    listeners = [Listener("--host", "0.0.0.0", False, "move the robot"),
                 Listener("--zenoh-listen", "tcp/10.0.0.1:7447", False, "command the robot"),
                 Listener("--state-endpoint", "tcp://0.0.0.0:5560", True, "read the state"),   # CURVE: fine
                 Listener("--host", "127.0.0.2", False, "move the robot")]                    # loopback: fine
    check_listeners("aioadept x", listeners, insecure=True)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aioadept x: warning: --insecure: ")
    assert "0.0.0.0" in err[0] and "tcp/10.0.0.1:7447" in err[0] and "5560" not in err[0] and "127.0.0.2" not in err[0]
    with pytest.raises(ValueError, match="--host '0.0.0.0'"):
        check_listeners("aioadept x", listeners, insecure=False)
    check_listeners("aioadept x", listeners[2:], insecure=False)   # authenticated or loopback: no word
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize(("host", "loopback"), [("127.0.0.1", True), ("127.0.0.2", True), ("::1", True),
                                                 ("[::1]", True), ("localhost", True), ("0.0.0.0", False),
                                                 ("*", False), ("::", False), ("", False), ("192.168.1.5", False),
                                                 ("robot.local", False)])
def test_loopback_is_127_slash_8_and_the_ipv6_one(host, loopback):
    assert is_loopback(host) is loopback


@zenoh_needed
@pytest.mark.timeout(60)
async def test_the_bridge_says_who_may_command_the_robot(tmp_path):
    from aioadept.testing.nodes import running_node

    from bustransports import free_port

    router = start_zenoh_router()
    listen = f"tcp/127.0.0.1:{free_port()}"
    async with running_node("sim", "--port", "0", "--state-endpoint", "none", log_path=tmp_path / "sim.log") as sim:
        robot = ["--robot", f"127.0.0.1:{sim.ready['port']}", "--stop-port", sim.ready["stop_port"]]
        async with running_node("bridge", *robot, "--zenoh-listen", listen, "--cell", "who", "--name", "r1",
                                log_path=tmp_path / "router.log"):
            pass
        async with running_node("bridge", *robot, "--zenoh-connect", router, "--cell", "who", "--name", "r2",
                                log_path=tmp_path / "client.log"):
            pass
    said = (tmp_path / "router.log").read_text()
    assert (f"aioadept bridge: any process on this machine that reaches {listen} may command aioadept/who/r1 "
            "(no Zenoh credentials configured)") in said
    said = (tmp_path / "client.log").read_text()
    assert f"aioadept bridge: any process that reaches the Zenoh router at {router} may command aioadept/who/r2" in said
