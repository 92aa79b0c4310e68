"""``--mode sweep`` and the sweep's cell values are checked before anything starts: exit 2, one line on
stderr naming the file, table and key (or the option), no run folder. The commands run as a user runs them (``python -m aioadept``), one row of each table so and the
others in this process (tests/integration/cliinproc.py), the same assertions on the exit status and stderr."""

from __future__ import annotations

import subprocess

import pytest

from cliinproc import run_inproc
from cliinproc import run_real as run

pytestmark = pytest.mark.timeout(60)


def one_line(proc: subprocess.CompletedProcess[str]) -> str:
    assert "Traceback" not in proc.stdout + proc.stderr, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr
    return lines[0]


BAD_SWEEP_VALUES = [
    ("mode = \"fast\"", "mode = 'fast': expected one of stepwise, sweep"),
    ("max_blur_fraction = 0", "max_blur_fraction = 0.0: expected a number > 0 and <= 1"),
    ("frame_interval_s = 0", "frame_interval_s = 0.0: expected a number in 0.001..1 s"),
    ("max_sweeps = 0", "max_sweeps = 0: expected an integer in 1..10"),
    ("sweep_range_mm = 500", "sweep_range_mm = 500.0: expected a number in 1..200 mm"),
    ("line_speed_mm_s = 0", "line_speed_mm_s = 0.0: expected a number in 1..10000 mm/s"),
]


@pytest.mark.parametrize("command", ["demo", "focus"])
@pytest.mark.parametrize(("line", "message"), BAD_SWEEP_VALUES, ids=[v[0] for v in BAD_SWEEP_VALUES])
def test_a_sweep_value_out_of_range_names_file_table_and_key(tmp_path, command, line, message):
    cfg = tmp_path / "cell.toml"
    cfg.write_text(f"[focus]\n{line}\n")
    runner = run if (command, line) == ("demo", 'mode = "fast"') else run_inproc
    proc = runner(command, "--config", str(cfg), "--out", str(tmp_path / "runs"), cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert one_line(proc) == f"aioadept {command}: {cfg} [focus]: {message}"
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize("command", ["demo", "focus"])
def test_an_exposure_too_long_for_a_sweep_is_refused_from_the_file_and_from_the_option(tmp_path, command):
    cfg = tmp_path / "cell.toml"
    cfg.write_text("[vision]\nexposure_ms = 200.0\n")
    runner = run if command == "demo" else run_inproc
    proc = runner(command, "--config", str(cfg), "--mode", "sweep", "--out", str(tmp_path / "runs"), cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    line = one_line(proc)
    assert line.startswith(f"aioadept {command}: max_blur_fraction = 0.34 of depth_of_field_mm = 3 with "
                           "exposure_ms = 200 allows 5.1 mm/s")
    assert line.endswith('use mode = "stepwise"')
    assert not (tmp_path / "runs").exists()
    cfg.write_text("[vision]\nexposure_ms = 200.0\n[focus]\nmode = \"sweep\"\n")
    proc = runner(command, "--config", str(cfg), "--out", str(tmp_path / "runs"), cwd=tmp_path)
    assert proc.returncode == 2 and one_line(proc).startswith(f"aioadept {command}: max_blur_fraction = 0.34")
    # The stepwise loop has no blur budget: the same file with --mode stepwise gets past the checks (and then
    # fails to connect, exit 1, in focus: nothing runs there; a real process, as it gets as far as connecting).
    if command == "focus":
        proc = run(command, "--config", str(cfg), "--mode", "stepwise", "--robot", "127.0.0.1:9",
                   "--out", str(tmp_path / "runs"), cwd=tmp_path)
        assert proc.returncode == 1 and "max_blur" not in proc.stderr


def test_a_sim_too_fast_for_the_sweep_says_so(tmp_path):
    proc = run_inproc("demo", "--mode", "sweep", "--time-scale", "50", "--out", str(tmp_path / "runs"), cwd=tmp_path)
    assert proc.returncode == 2
    assert "at time_scale 50" in one_line(proc)
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize("command", ["demo", "focus"])
def test_an_unknown_mode_is_one_line(tmp_path, command):
    runner = run if command == "demo" else run_inproc
    proc = runner(command, "--mode", "fast", cwd=tmp_path)
    assert proc.returncode == 2
    assert "--mode" in one_line(proc) and "'fast'" in proc.stderr
    help_text = " ".join(runner(command, "--help", cwd=tmp_path).stdout.split())
    assert "--mode {stepwise,sweep}" in help_text
