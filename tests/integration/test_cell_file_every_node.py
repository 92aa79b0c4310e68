"""One cell file for every node: ``aioadept sim --config`` reads the ``[robot]`` table,
``aioadept vision --state-endpoint none`` is accepted as in ``sim``, and the vision node's READY line prints each
link both as the node uses it and in the form the MCN must use.

The nodes run as real processes on 127.0.0.1 (``python -m aioadept``), each with a hard time cap.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from aioadept.bus.endpoints import opposite
from aioadept.cli.sim import build_parser, parse_args

AIOADEPT = [sys.executable, "-m", "aioadept"]
EXAMPLE = Path(__file__).parents[2] / "examples" / "cell.toml"


def _ready(*args: str) -> dict[str, str]:
    """Start ``aioadept ARGS``, read its READY line, stop it with SIGINT; the line's fields."""
    proc = subprocess.Popen([*AIOADEPT, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith("READY "), (line, proc.stderr.read() if proc.poll() is not None else "")
        return dict(kv.split("=", 1) for kv in line.split()[1:])
    finally:
        proc.send_signal(2)
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


def test_sim_config_reads_the_robot_table_and_the_command_line_overrides_it(tmp_path):
    cell = tmp_path / "cell.toml"
    cell.write_text('[robot]\nhost = "127.0.0.1"\nport = 0\ntime_scale = 5.0\nmonitor_speed = 40\n'
                    'state_endpoint = "none"\nsim_args = ["--max-speed", "50"]\n[focus]\ndelta_z_mm = 2.5\n')
    args = parse_args(build_parser(), ["--config", str(cell)])
    assert (args.host, args.port, args.time_scale, args.monitor_speed, args.state_endpoint, args.max_speed) == \
        ("127.0.0.1", 0, 5.0, 40, "none", 50.0)
    args = parse_args(build_parser(), ["--config", str(cell), "--time-scale", "2", "--max-speed", "80"])
    assert (args.time_scale, args.max_speed) == (2.0, 80.0)


def test_sim_config_reads_the_example_cell_file():
    args = parse_args(build_parser(), ["--config", str(EXAMPLE)])
    assert (args.port, args.state_endpoint, args.stop_port) == (1234, "tcp://127.0.0.1:5560", "1235")


def test_sim_config_stop_port_zero_is_the_port_plus_one_and_the_command_line_overrides_it(tmp_path):
    cell = tmp_path / "cell.toml"
    cell.write_text('[robot]\nport = 4000\nstop_port = 0\n')
    assert parse_args(build_parser(), ["--config", str(cell)]).stop_port == "auto"
    cell.write_text('[robot]\nport = 4000\nstop_port = 4100\n')
    assert parse_args(build_parser(), ["--config", str(cell)]).stop_port == "4100"
    assert parse_args(build_parser(), ["--config", str(cell), "--stop-port", "none"]).stop_port == "none"


@pytest.mark.timeout(60)
def test_sim_config_serves_where_the_robot_table_says(tmp_path):
    cell = tmp_path / "cell.toml"
    cell.write_text('[robot]\nport = 0\nstate_endpoint = "tcp://127.0.0.1:0"\n')
    ready = _ready("sim", "--config", str(cell))
    assert ready["host"] == "127.0.0.1" and int(ready["port"]) > 0
    assert ready["state"].startswith("tcp://127.0.0.1:") and not ready["state"].endswith(":0")


@pytest.mark.timeout(60)
@pytest.mark.parametrize(("text", "message"), [
    ('[robot]\nport = -1\n', "[robot]: port = -1: expected an integer in 0..65535"),
    ('[robot]\ntime_scale = 0\n', "[robot]: time_scale = 0.0: expected a number > 0"),
    ('[robot]\nhots = "x"\n', "[robot]: unknown key(s) hots"),
])
def test_sim_config_mistake_is_one_line_exit_2(tmp_path, text, message):
    cell = tmp_path / "cell.toml"
    cell.write_text(text)
    proc = subprocess.run([*AIOADEPT, "sim", "--config", str(cell)], capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"aioadept sim: {cell} {message}"), proc.stderr
    assert len(proc.stderr.splitlines()) == 1 and proc.stdout == ""


@pytest.mark.timeout(60)
def test_vision_state_endpoint_none_is_accepted_and_the_ready_line_names_both_sides():
    ready = _ready("vision", "--state-endpoint", "none", "--request-endpoint", "@tcp://127.0.0.1:0",
                   "--response-endpoint", "tcp://127.0.0.1:0")
    assert ready["state"] == "none"
    # The node binds both (its request SUB by '@', its response PUB by default): it says so, with the real ports...
    assert ready["node_request"].startswith("@tcp://127.0.0.1:") and not ready["node_request"].endswith(":0")
    assert ready["node_response"].startswith("@tcp://127.0.0.1:")
    # ...and request=/response= are the MCN's side of the same links: connect there.
    assert ready["request"] == opposite(ready["node_request"]) == ">" + ready["node_request"][1:]
    assert ready["response"] == opposite(ready["node_response"])


@pytest.mark.timeout(60)
def test_vision_ready_line_when_the_node_connects_its_request_sub():
    ready = _ready("vision", "--state-endpoint", "None", "--request-endpoint", "tcp://127.0.0.1:5999",
                   "--response-endpoint", "tcp://127.0.0.1:0")
    assert ready["node_request"] == ">tcp://127.0.0.1:5999"  # the bare default connects (as EPypes nodes do)
    assert ready["request"] == "@tcp://127.0.0.1:5999"  # so the MCN binds its PUB there
