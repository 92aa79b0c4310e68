"""A newcomer's mistakes at the command line get one clear line and a documented exit code.

The tests run the real ``aioadept`` console entry (``python -m aioadept``) in a subprocess, as a user would; a table
of mistakes caught before anything starts runs one row so and the others in this process (tests/integration/
cliinproc.py), the same assertions on the exit status and stderr.
"""

from __future__ import annotations

import contextlib
import socket
import subprocess
import threading

import pytest

from aioadept.ports import free_port

from cliinproc import AIOADEPT, run_inproc
from cliinproc import run_real as run


def one_error_line(proc: subprocess.CompletedProcess[str]) -> str:
    """The stderr of a failed command: exactly one line, and no traceback."""
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr
    return lines[0]


# ------------------------------------------------------------------------------------ config mistakes (item 2)
BAD_CONFIGS = {
    "unknown_key": ('[focus]\ndelta_z_mmm = 2.0\n', ["[focus]", "delta_z_mmm", "delta_z_mm"]),
    "wrong_type": ('[focus]\ndelta_z_mm = "2.0"\n', ["[focus]", "delta_z_mm", "expected a number", "string"]),
    "wrong_type_bool": ('[robot]\nstart_sim = "no"\n', ["[robot]", "start_sim", "true or false"]),
    "bad_toml": ('[focus]\ndelta_z_mm = 2.0\nmax_steps = \n', ["not valid TOML", "line 3"]),
    "unknown_section": ('[camera]\nfps = 3\n', ["camera", "expected"]),
}


@pytest.mark.timeout(60)
@pytest.mark.parametrize("command", ["demo", "focus", "experiment", "vision"])
@pytest.mark.parametrize("case", sorted(BAD_CONFIGS))
def test_a_config_mistake_is_one_line_naming_file_and_key_with_exit_2(tmp_path, command, case):
    text, words = BAD_CONFIGS[case]
    cfg = tmp_path / "cell.toml"
    cfg.write_text(text)
    out = [] if command == "vision" else ["--out", str(tmp_path / "runs")]  # the node has no run folder
    runner = run if (command, case) == ("demo", "unknown_key") else run_inproc
    proc = runner(command, "--config", str(cfg), *out, cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    line = one_error_line(proc)
    assert line.startswith(f"aioadept {command}: {cfg}"), line
    for w in words:
        assert w in line, (w, line)
    assert not (tmp_path / "runs").exists()  # nothing was started, no run folder


@pytest.mark.timeout(60)
@pytest.mark.parametrize("command", ["demo", "focus", "experiment", "vision"])
def test_a_missing_config_file_is_one_line(tmp_path, command):
    runner = run if command == "focus" else run_inproc
    proc = runner(command, "--config", str(tmp_path / "nope.toml"), cwd=tmp_path)
    assert proc.returncode == 2
    assert one_error_line(proc) == f"aioadept {command}: {tmp_path / 'nope.toml'}: no such file"


@pytest.mark.timeout(60)
def test_verbose_shows_the_traceback_of_a_config_mistake(tmp_path):
    cfg = tmp_path / "cell.toml"
    cfg.write_text('[focus]\ndelta_z_mm = "2.0"\n')
    proc = run_inproc("focus", "--config", str(cfg), "-v", cwd=tmp_path)
    assert proc.returncode == 2
    assert "Traceback" in proc.stderr and "ConfigError" in proc.stderr
    assert proc.stderr.rstrip().splitlines()[-1].startswith(f"aioadept focus: {cfg}")


@pytest.mark.timeout(60)
def test_vision_config_mistakes_use_the_same_reader(tmp_path):
    cfg = tmp_path / "vision.toml"
    cfg.write_text("fps = \n")
    proc = run_inproc("vision", "--config", str(cfg), cwd=tmp_path)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert f"{cfg}: not valid TOML" in proc.stderr and "line 1" in proc.stderr


# --------------------------------------------------------------- demo --config with start_sim = false (item 1)
@pytest.mark.timeout(60)
def test_demo_with_start_sim_false_connects_to_the_configured_address_and_fails_if_nothing_is_there(tmp_path):
    port = free_port()  # nothing listens here
    cfg = tmp_path / "cell.toml"
    cfg.write_text(f'[robot]\nstart_sim = false\nhost = "127.0.0.1"\nport = {port}\nconnect_timeout_s = 2.0\n'
                   f'[vision]\nstart = false\n[run]\nout_dir = "{tmp_path / "runs"}"\n')
    proc = run("demo", "--config", str(cfg), cwd=tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "inspection-start pose" not in proc.stdout
    line = one_error_line(proc)  # one line on stderr, naming the address
    assert line.startswith(f"aioadept demo failed: connect to 127.0.0.1:{port}: "), line
    # No sim of its own was started, and a connection that never succeeded leaves no run folder.
    assert list((tmp_path / "runs").iterdir()) == []


@pytest.mark.timeout(120)
def test_demo_with_start_sim_false_uses_the_running_server(tmp_path):
    sim = subprocess.Popen([*AIOADEPT, "sim", "--port", "0", "--time-scale", "10", "--state-endpoint",
                            "tcp://127.0.0.1:0"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert sim.stdout is not None
        ready = dict(kv.split("=", 1) for kv in sim.stdout.readline().split()[1:])
        cfg = tmp_path / "cell.toml"
        cfg.write_text(f'[robot]\nstart_sim = false\nhost = "{ready["host"]}"\nport = {ready["port"]}\n'
                       f'state_endpoint = "{ready["state"]}"\n'
                       '[vision]\nrequest_endpoint = "tcp://127.0.0.1:0"\nresponse_endpoint = "tcp://127.0.0.1:0"\n'
                       f'[run]\nout_dir = "{tmp_path / "runs"}"\nanalyze = false\nrecord = false\n')
        proc = run("demo", "--config", str(cfg), timeout=110, cwd=tmp_path)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert "inspection-start pose" in proc.stdout
        (run_dir,) = (tmp_path / "runs").iterdir()
        assert not (run_dir / "logs" / "sim.log").exists()  # it used our sim, not one of its own
        assert (run_dir / "logs" / "vision.log").exists()  # vision.start (default true) is still honoured
        assert sim.poll() is None
    finally:
        sim.terminate()
        sim.wait(10)


# ------------------------------------------------------------------ the wrong kind of port (item 3)
@contextlib.contextmanager
def silent_tcp_server():
    """A TCP port that accepts connections and never says anything (the kernel completes the handshake)."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(8)
    try:
        yield s.getsockname()[1]
    finally:
        s.close()


@contextlib.contextmanager
def zmq_port():
    """A bound ZeroMQ socket, as a vision node's response port is."""
    import zmq

    ctx = zmq.Context()
    sock = ctx.socket(zmq.PUB)
    sock.setsockopt(zmq.LINGER, 0)
    port = sock.bind_to_random_port("tcp://127.0.0.1")
    try:
        yield port
    finally:
        sock.close()
        ctx.term()


@contextlib.contextmanager
def http_server():
    """A real HTTP server (the standard library's), which answers our hello line with an HTML error page."""
    from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

    httpd = ThreadingHTTPServer(("127.0.0.1", 0), BaseHTTPRequestHandler)
    httpd.daemon_threads = True
    t = threading.Thread(target=httpd.serve_forever, daemon=True)
    t.start()
    try:
        yield httpd.server_address[1]
    finally:
        httpd.shutdown()
        httpd.server_close()


WHAT_ANSWERED = {
    silent_tcp_server: "(it sent nothing)",
    zmq_port: r"(it sent b'\xff\x00\x00\x00\x00\x00\x00\x00\x01\x7f': a ZeroMQ greeting",
    http_server: "(it sent b'<!DOCTYPE HTML>': an HTTP server; then it closed the connection)",
}


@pytest.mark.timeout(40)
@pytest.mark.parametrize("server", [silent_tcp_server, zmq_port, http_server])
def test_send_to_something_that_is_not_a_robot_server_says_so_in_one_line(server):
    with server() as port:
        proc = run("send", "--port", str(port), "here", timeout=30)  # today: silent for the 60 s ack timeout
    assert proc.returncode == 3, proc.stdout + proc.stderr
    line = one_error_line(proc)  # the HTTP server's page is not echoed: one line
    assert line.startswith(f"aioadept send: 127.0.0.1:{port} answered nothing like a RobotServer within 2 s "
                           f"{WHAT_ANSWERED[server]}"), line
    assert line.endswith("is this the robot's port?")
    assert proc.stdout == ""


@pytest.mark.timeout(40)
def test_focus_against_a_zeromq_port_says_so(tmp_path):
    with zmq_port() as port:
        proc = run("focus", "--robot", f"127.0.0.1:{port}", "--out", str(tmp_path), timeout=30, cwd=tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    line = one_error_line(proc)  # one line, naming the address and what answered
    assert line.startswith(f"aioadept focus failed: 127.0.0.1:{port} answered nothing like a RobotServer within "
                           r"2 s (it sent b'\xff\x00\x00\x00\x00\x00\x00\x00\x01\x7f': a ZeroMQ greeting"), line
    assert line.endswith("): is this the robot's port?"), line  # "; then it closed the connection" if it did
    assert proc.stdout == ""
    assert list(tmp_path.glob("*focus-*")) == []  # no run folder for a connection that never succeeded


@pytest.mark.timeout(30)
def test_send_goes_on_with_a_server_that_answers_hello_with_unknown_skill():
    import asyncio

    from aioadept.testing import Reply, ScriptedServer

    async def main() -> tuple[int, str, str]:
        async with ScriptedServer({"hello": Reply.error(-406, "unknown skill")}) as server:
            proc = await asyncio.create_subprocess_exec(
                *AIOADEPT, "send", "--port", str(server.port), "set_speed:20",
                stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
            out, err = await proc.communicate()
            assert [line.split(b":")[1] for line in server.lines()] == [b"hello", b"set_speed"]
            return proc.returncode, out.decode(), err.decode()

    code, out, err = asyncio.run(main())
    assert code == 0, err
    assert out.split()[1:3] == ["set_speed", "done"]


@pytest.mark.timeout(30)
@pytest.mark.parametrize("address", ["127.0.0.1:abc", "127.0.0.1:99999", "127.0.0.1:"])
def test_focus_robot_address_mistake_is_one_line(tmp_path, address):
    runner = run if address == "127.0.0.1:abc" else run_inproc
    proc = runner("focus", "--robot", address, "--out", str(tmp_path / "runs"), cwd=tmp_path)
    assert proc.returncode == 2
    line = one_error_line(proc)
    assert "HOST[:PORT]" in line and address in line
    assert not (tmp_path / "runs").exists()


def test_focus_robot_without_a_port_means_port_1234():
    # Not run against 127.0.0.1:1234 itself: whatever listens there on this machine is not ours to move.
    from aioadept.cli.options import parse_robot_address

    assert parse_robot_address("127.0.0.1") == ("127.0.0.1", 1234)
    assert parse_robot_address("10.0.0.5:2000") == ("10.0.0.5", 2000)


# ------------------------------------------------------------------ send with the arguments as words (item 4)
@pytest.mark.timeout(30)
def test_send_with_arguments_as_separate_words_shows_the_right_form():
    proc = run("send", "move_to", "300", "0", "500", "0", "180", "0")
    assert proc.returncode == 2
    line = one_error_line(proc)
    assert "SKILL[:ARG,ARG,...]" in line
    assert "did you mean 'aioadept send move_to:300,0,500,0,180,0'?" in line


@pytest.mark.timeout(30)
def test_send_with_a_bad_skill_name_shows_an_example():
    proc = run_inproc("send", "Move_To:1,2")
    assert proc.returncode == 2
    line = one_error_line(proc)
    assert "e.g. 'aioadept send move_to:300,0,500,0,180,0 break'" in line
