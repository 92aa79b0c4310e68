"""The cell file's [vision] trigger, exposure_ms and pixel_format keys: validated in one line, passed to the node."""

from __future__ import annotations

import pytest

from aioadept.apps.cell import vision_argv
from aioadept.cell.config import CellConfig
from aioadept.errors import ConfigError


def test_defaults_are_software_trigger_where_possible_and_5_ms():
    v = vision_argv(CellConfig())
    assert v[v.index("--trigger") + 1] == "auto"
    assert float(v[v.index("--exposure-ms") + 1]) == 5.0 and v[v.index("--pixel-format") + 1] == "Mono8"


def test_configured_values_reach_the_node_command_line():
    cfg = CellConfig.from_dict({"vision": {"source": "gige:192.168.10.20", "trigger": "software",
                                           "exposure_ms": 2, "pixel_format": "Mono16"}})
    v = vision_argv(cfg)
    assert v[v.index("--source") + 1] == "gige:192.168.10.20"
    assert v[v.index("--trigger") + 1] == "software"
    assert float(v[v.index("--exposure-ms") + 1]) == 2.0 and v[v.index("--pixel-format") + 1] == "Mono16"


@pytest.mark.parametrize("vision, words", [
    ({"trigger": "hardware"}, ['trigger = "hardware"', "auto", "software", "free"]),
    ({"exposure_ms": 0}, ["exposure_ms = 0.0", "> 0"]),
    ({"exposure_ms": float("inf")}, ["exposure_ms = inf"]),
    ({"exposure_ms": "5"}, ["exposure_ms", "expected"]),
    ({"pixel_format": "RGB8"}, ['pixel_format = "RGB8"', "Mono8"]),
    ({"policy": "latest"}, ['policy = "latest"', "after", "nearest"]),
])
def test_bad_values_are_one_line_naming_file_key_and_expectation(vision, words):
    with pytest.raises(ConfigError) as info:
        CellConfig.from_dict({"vision": vision}, source="cell.toml")
    msg = str(info.value)
    assert msg.startswith("cell.toml [vision]: ") and "\n" not in msg
    for w in words:
        assert w in msg
