"""The cell description: TOML parsing, validation and port resolution."""

from pathlib import Path

import pytest

from aioadept.apps.cell import resolve_ports, sim_argv, vision_argv
from aioadept.cell.config import CellConfig
from aioadept.apps.processes import parse_ready

EXAMPLE = Path(__file__).parents[3] / "examples" / "cell.toml"


def test_example_cell_file_parses_into_every_section():
    cfg = CellConfig.from_toml(EXAMPLE)
    assert cfg.robot.port == 1234
    assert cfg.vision.request_endpoint == "tcp://127.0.0.1:5555"
    assert cfg.focus.delta_z_mm == 2.0 and cfg.focus.approach_speed == 25
    assert cfg.run.analyze is True


def test_unknown_section_and_key_are_named_in_the_error():
    with pytest.raises(ValueError, match="unknown section"):
        CellConfig.from_dict({"robto": {}})
    with pytest.raises(ValueError, match=r"\[robot\]: unknown key\(s\) prot; expected one of host"):
        CellConfig.from_dict({"robot": {"prot": 1}})


def test_port_zero_resolves_to_distinct_free_ports_for_started_nodes_only():
    cfg = CellConfig.from_dict({"robot": {"port": 0, "state_endpoint": "tcp://127.0.0.1:0"},
                                "vision": {"request_endpoint": "tcp://127.0.0.1:0",
                                           "response_endpoint": "tcp://127.0.0.1:*"}})
    r = resolve_ports(cfg)
    ports = [r.robot.port] + [int(e.rsplit(":", 1)[1]) for e in
                              (r.robot.state_endpoint, r.vision.request_endpoint, r.vision.response_endpoint)]
    assert all(p > 0 for p in ports)
    assert cfg.robot.port == 0, "the input config is not modified"
    remote = CellConfig.from_dict({"robot": {"port": 0, "start_sim": False}})
    assert resolve_ports(remote).robot.port == 0


def test_node_command_lines_carry_the_addresses():
    cfg = CellConfig()
    assert sim_argv(cfg)[:5] == ["sim", "--host", "127.0.0.1", "--port", "1234"]
    v = vision_argv(cfg)
    assert v[v.index("--state-endpoint") + 1] == cfg.robot.state_endpoint
    assert v[v.index("--request-endpoint") + 1] == cfg.vision.request_endpoint


def test_ready_line_parsing():
    assert parse_ready("READY host=127.0.0.1 port=4321 state=tcp://127.0.0.1:5560") == {
        "host": "127.0.0.1", "port": "4321", "state": "tcp://127.0.0.1:5560"}
    with pytest.raises(ValueError):
        parse_ready("listening on 1234")
