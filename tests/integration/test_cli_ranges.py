"""A value out of range never starts a run: every option and cell-file value is checked before
anything starts (exit 2, one line on stderr, no run folder), and ``--help`` quotes the range the check enforces.

The commands run as a user runs them (``python -m aioadept`` in a subprocess): one row of each table so, the other
rows in this process (tests/integration/cliinproc.py), the same assertions on the exit status and stderr.
"""

from __future__ import annotations

import argparse
import asyncio
import subprocess
from pathlib import Path

import pytest

from aioadept.cell.config import CellConfig, RobotSection
from aioadept.apps.focus import FocusParams
from aioadept.cell.schema import Range, range_of
from aioadept.errors import ConfigError
from aioadept.vision.options import VisionOptions

from cliinproc import run_inproc
from cliinproc import run_real as run


def one_line(proc: subprocess.CompletedProcess[str]) -> str:
    assert "Traceback" not in proc.stdout + proc.stderr, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr
    return lines[0]


BAD_OPTIONS = [
    (["--delta-z", "0"], "--delta-z 0.0: expected a number in 0.1..50 mm"),
    (["--delta-z", "-2"], "--delta-z -2.0: expected a number in 0.1..50 mm"),
    (["--speed", "0"], "--speed 0: expected an integer in 1..100 %"),
    (["--speed", "150"], "--speed 150: expected an integer in 1..100 %"),
    (["--max-steps", "0"], "--max-steps 0: expected an integer in 1..1000"),
    (["--vision-timeout", "nan"], "--vision-timeout nan: expected a number > 0 s"),
    (["--vision-timeout", "0"], "--vision-timeout 0.0: expected a number > 0 s"),
]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("command", ["demo", "focus"])
@pytest.mark.parametrize(("option", "message"), BAD_OPTIONS, ids=lambda v: " ".join(v) if isinstance(v, list) else "")
def test_a_value_out_of_range_is_one_line_exit_2_and_no_run_folder(tmp_path, command, option, message):
    runner = run if (command, option) == ("demo", ["--delta-z", "0"]) else run_inproc
    proc = runner(command, *option, "--out", str(tmp_path / "runs"), cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert one_line(proc) == f"aioadept {command}: {message}"
    assert proc.stdout == ""
    assert not (tmp_path / "runs").exists()


@pytest.mark.timeout(60)
@pytest.mark.parametrize(("option", "message"), [
    (["--time-scale", "0"], "--time-scale 0.0: expected a number > 0"),
    (["--focus-offset-mm", "-3"], "--focus-offset-mm -3.0: expected a number >= 0 mm"),
    (["--speed", "abc"], "error: argument --speed: invalid int value: 'abc' (--speed SPEED; see aioadept demo --help)"),
])
def test_demo_only_options_are_checked_too(tmp_path, option, message):
    runner = run if option == ["--speed", "abc"] else run_inproc  # argparse's own error, in a real process
    proc = runner("demo", *option, "--out", str(tmp_path / "runs"), cwd=tmp_path)
    assert proc.returncode == 2
    assert one_line(proc) == f"aioadept demo: {message}"
    assert not (tmp_path / "runs").exists()


BAD_CELL_VALUES = [
    ("focus", "approach_speed = 0", "approach_speed = 0: expected an integer in 1..100 %"),
    ("focus", "delta_z_mm = -2.0", "delta_z_mm = -2.0: expected a number in 0.1..50 mm"),
    ("focus", "retract_speed = 101", "retract_speed = 101: expected an integer in 1..100 %"),
    ("robot", "time_scale = 0", "time_scale = 0.0: expected a number > 0"),
    ("robot", "monitor_speed = 0", "monitor_speed = 0: expected an integer in 1..100 %"),
    ("robot", "port = 70000", "port = 70000: expected an integer in 0..65535"),
    ("robot", "connect_timeout_s = 0", "connect_timeout_s = 0.0: expected a number > 0 s"),
    ("vision", "fps = 0", "fps = 0.0: expected a number > 0"),
    ("vision", "focus_offset_mm = -1", "focus_offset_mm = -1.0: expected a number >= 0 mm"),
]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("command", ["demo", "experiment"])
@pytest.mark.parametrize(("table", "line", "message"), BAD_CELL_VALUES, ids=[c[1] for c in BAD_CELL_VALUES])
def test_a_cell_file_value_out_of_range_names_file_table_and_key(tmp_path, command, table, line, message):
    cfg = tmp_path / "cell.toml"
    cfg.write_text(f"[{table}]\n{line}\n[run]\nout_dir = \"{tmp_path / 'runs'}\"\n")
    runner = run if (command, line) == ("demo", "approach_speed = 0") else run_inproc
    proc = runner(command, "--config", str(cfg), "--out", str(tmp_path / "runs"), cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert one_line(proc) == f"aioadept {command}: {cfg} [{table}]: {message}"
    assert not (tmp_path / "runs").exists()


@pytest.mark.timeout(60)
@pytest.mark.parametrize(("option", "message"), [
    (["--speeds", "0,25"], "--speeds 0.0: expected an integer in 1..100 %"),
    (["--speeds", "2.5"], "--speeds 2.5: expected an integer in 1..100 %"),
    (["--delta-z", "1.5,-1"], "--delta-z -1.0: expected a number in 0.1..50 mm"),
    (["--runs", "0"], "--runs 0: expected an integer >= 1"),
])
def test_experiment_checks_every_grid_value_before_starting(tmp_path, option, message):
    runner = run if option == ["--runs", "0"] else run_inproc
    proc = runner("experiment", *option, "--out", str(tmp_path / "exp"), cwd=tmp_path)
    assert proc.returncode == 2
    assert one_line(proc) == f"aioadept experiment: {message}"
    assert not (tmp_path / "exp").exists()


# ------------------------------------------------------------------------------- the help says the same range
def _help(command: str, tmp_path: Path) -> str:
    proc = (run if command == "demo" else run_inproc)(command, "--help", cwd=tmp_path)
    assert proc.returncode == 0
    return " ".join(proc.stdout.split())


@pytest.mark.timeout(60)
@pytest.mark.parametrize("command", ["demo", "focus"])
def test_help_states_the_ranges_the_check_enforces(tmp_path, command):
    text = _help(command, tmp_path)
    for option, name in (("--speed", "approach_speed"), ("--delta-z", "delta_z_mm"),
                         ("--max-steps", "max_steps"), ("--vision-timeout", "vision_timeout_s")):
        rng = range_of(FocusParams, name)
        assert f"({rng.text}; default" in text, (option, rng.text)
    assert "0..100" not in text  # the old help's speed range, which the check never allowed


@pytest.mark.parametrize(("cls", "name"), [
    (FocusParams, "approach_speed"), (FocusParams, "delta_z_mm"), (FocusParams, "max_steps"),
    (FocusParams, "vision_timeout_s"), (RobotSection, "time_scale"), (VisionOptions, "focus_offset_mm"),
])
def test_the_bounds_the_help_quotes_are_the_bounds_the_check_uses(cls, name):
    """Just inside each quoted bound passes the check, just outside fails it."""
    rng: Range = range_of(cls, name)
    step = 1 if rng.integer else 1e-6
    inside = [rng.lo + (step if rng.lo_open else 0)]
    outside = [rng.lo if rng.lo_open else rng.lo - step, float("nan"), float("inf")]
    if rng.hi != float("inf"):
        inside.append(rng.hi)
        outside.append(rng.hi + step)
    for v in inside:
        rng.check(name, v)
    for v in outside:
        with pytest.raises(ValueError, match=name):
            rng.check(name, v)


def test_a_cell_config_value_out_of_range_is_a_config_error():
    with pytest.raises(ConfigError, match=r"^cell.toml \[focus\]: delta_z_mm = 0.0: expected"):
        CellConfig.from_dict({"focus": {"delta_z_mm": 0}}, source="cell.toml")


def test_apply_overrides_names_the_option():
    from aioadept.cli.demo import build_parser
    from aioadept.cli.options import apply_overrides

    args = build_parser().parse_args(["--delta-z", "-2"])
    with pytest.raises(ValueError, match=r"^--delta-z -2.0: expected a number in 0.1..50 mm$"):
        apply_overrides(CellConfig(), args)
    ok = apply_overrides(CellConfig(), build_parser().parse_args(["--delta-z", "1.5", "--speed", "100"]))
    assert (ok.focus.delta_z_mm, ok.focus.approach_speed) == (1.5, 100)
    assert isinstance(args, argparse.Namespace)


class _NoMotion:
    """A robot that fails the test if anything is sent to it."""

    async def cmdexec(self, *commands):  # noqa: ANN002, ANN201
        raise AssertionError(f"a command was sent: {commands}")

    cmdexec_joined = cmdexec


@pytest.mark.parametrize(("delta_z", "speed"), [(0.0, 25), (-2.0, 25), (2.0, 0), (2.0, 150)])
def test_ufloop_refuses_a_bad_value_before_any_motion(delta_z, speed):
    from aioadept.apps.paper import ufloop

    with pytest.raises(ValueError, match="expected"):
        asyncio.run(ufloop(_NoMotion(), None, delta_z, speed))
