"""The arm is chosen in one place: ``--robot-model`` or the cell file's ``[robot] model`` (the sim a cell starts gets
it), a wrong name is one line naming the file or option and the known models."""

from __future__ import annotations

import pytest

from aioadept.apps.cell import sim_argv
from aioadept.cell.config import CellConfig
from aioadept.cli.sim import build_parser, options_from_args, parse_args
from aioadept.cell.schema import report


def _cell(tmp_path, model: str):
    p = tmp_path / "cell.toml"
    p.write_text(f'[robot]\nmodel = "{model}"\n')
    return p


def test_the_cell_files_model_reaches_the_sim_it_starts(tmp_path):
    cfg = CellConfig.from_toml(_cell(tmp_path, "cobra-s800"))
    argv = sim_argv(cfg)
    assert argv[argv.index("--robot-model") + 1] == "cobra-s800"
    args = parse_args(build_parser(), ["--config", str(_cell(tmp_path, "cobra-s800"))])
    options = options_from_args(args)
    assert options.robot_model == "cobra-s800"
    ctl = options.make_controller()
    assert ctl.model.name == "cobra-s800" and len(ctl.joints_deg) == 4


def test_the_command_line_wins_over_the_cell_file(tmp_path):
    args = parse_args(build_parser(), ["--config", str(_cell(tmp_path, "cobra-s800")), "--robot-model",
                                       "viper-s650"])
    assert options_from_args(args).make_controller().model.name == "viper-s650"


def test_an_unknown_model_in_the_cell_file_is_one_line(tmp_path, capsys):
    path = _cell(tmp_path, "puma-560")
    with pytest.raises(ValueError) as info:
        CellConfig.from_toml(path)
    assert report("aioadept sim", info.value) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and "[robot]: unknown robot model 'puma-560'" in err[0]


def test_joints_of_a_four_axis_arm_come_first_and_the_rest_must_be_zero(capsys):
    args = parse_args(build_parser(), ["--robot-model", "cobra-s600", "--joints", "10,90,50,20,0,0"])
    assert options_from_args(args).make_controller().joints_deg == (10.0, 90.0, 50.0, 20.0)
    from aioadept.cli.sim import main

    with pytest.raises(SystemExit) as info:
        main(["--robot-model", "cobra-s600", "--joints", "10,90,50,20,5,0"])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "the cobra-s600 has 4 joints: J5.. must be 0" in err
