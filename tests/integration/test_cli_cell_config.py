"""One cell schema: ``examples/cell.toml`` loads in every subcommand that takes ``--config``.

Before, ``aioadept vision --config examples/cell.toml`` failed with "unknown options ['start']": the node and the
cell described the vision options in two schemas. Each test runs the real console entry in a subprocess, on a path
that reads the file and then stops quickly (no robot is moved).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from aioadept.apps.cell import vision_argv
from aioadept.cell.config import CellConfig
from aioadept.ports import free_port
from aioadept.cli.vision import resolve_options

ROOT = Path(__file__).resolve().parents[2]
CELL = ROOT / "examples" / "cell.toml"
AIOADEPT = [sys.executable, "-m", "aioadept"]


def run(*args: str, cwd: Path, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*AIOADEPT, *args], capture_output=True, text=True, timeout=timeout, cwd=cwd)


@pytest.mark.timeout(60)
def test_vision_reads_the_cell_file(tmp_path):
    # --figures reads every option, writes the pictures and exits: the config was accepted.
    proc = run("vision", "--config", str(CELL), "--figures", str(tmp_path / "figs"), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "unknown" not in proc.stderr
    assert any((tmp_path / "figs").iterdir())


def test_vision_takes_the_cell_files_vision_table_and_the_robots_state_endpoint(tmp_path):
    cfg = tmp_path / "cell.toml"
    cfg.write_text('[robot]\nstate_endpoint = "tcp://127.0.0.1:6001"\n'
                   '[vision]\nstart = false\nfps = 7.5\nbuffer_size = 9\nvision_args = ["--seed", "3"]\n')
    opts = resolve_options(["--config", str(cfg), "--fps", "9"])
    assert opts.fps == 9.0  # the command line overrides the file
    assert opts.buffer_size == 9 and opts.seed == 3  # node options and the starter's vision_args
    assert opts.state_endpoint == "tcp://127.0.0.1:6001"
    assert not hasattr(opts, "start")


def test_the_cell_passes_every_vision_option_to_the_node(tmp_path):
    cfg = CellConfig.from_dict({"vision": {"buffer_size": 9, "source": ["virtual", "folder:/x"], "inline": True}})
    argv = vision_argv(cfg)
    assert argv[argv.index("--buffer-size") + 1] == "9" and "--inline" in argv
    assert [argv[i + 1] for i, a in enumerate(argv) if a == "--source"] == ["virtual", "folder:/x"]
    # and the node parses exactly what the cell writes
    opts = resolve_options(argv[1:])
    assert opts.buffer_size == 9 and opts.graph_thread == "never" and opts.source == ["virtual", "folder:/x"]


def test_a_bad_source_in_the_cell_file_names_the_key_and_the_file(tmp_path):
    cfg = tmp_path / "cell.toml"
    cfg.write_text('[vision]\nsource = "webcam"\n')
    proc = run("vision", "--config", str(cfg), cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [f"aioadept vision: {cfg} [vision]: source: bad source 'webcam': use "
                                                "virtual, world, gige:ADDRESS, folder:PATH or opencv:SPEC"]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("command", ["focus", "demo", "experiment"])
def test_the_cell_file_loads_in_the_cell_commands(tmp_path, command):
    # A robot port where nothing listens: the file is read, the run starts and fails to connect at once (exit 1),
    # never a configuration error (exit 2). demo/experiment start no node here (start_sim/start = false).
    port = free_port()
    text = CELL.read_text().replace("start_sim = true", "start_sim = false").replace("start = true", "start = false")
    text = text.replace("port = 1234", f"port = {port}")
    cfg = tmp_path / "cell.toml"
    cfg.write_text(text)
    extra = ["--speeds", "25", "--delta-z", "2", "--runs", "1"] if command == "experiment" else ["--no-analyze"]
    proc = run(command, "--config", str(cfg), "--out", str(tmp_path / "runs"), *extra,
               cwd=tmp_path)
    assert proc.returncode not in (0, 2), proc.stdout + proc.stderr
    assert "unknown" not in proc.stderr and "expected" not in proc.stderr.split("Connect")[0]


@pytest.mark.timeout(180)
def test_demo_runs_the_shipped_v_plus_server_from_a_cell_file(tmp_path):
    """``sim_args = ["--vplus", ...]`` in ``[robot]``: the demo maps the V+ program's own ports (rs.port 1234, rs.sport
    1235) to the cell's free ports, so the focus run reaches the V+ server and its stop port (before, the sim was
    started with --stop-port, which --vplus refuses, and never listened on the cell's port)."""
    import json

    root = Path(__file__).resolve().parents[2]
    files = ", ".join(f'"{root / "vplus" / f}"' for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2"))
    cfg = tmp_path / "cell.toml"
    cfg.write_text(f'[robot]\nport = 0\ntime_scale = 10.0\nstate_endpoint = "tcp://127.0.0.1:0"\n'
                   f'sim_args = ["--vplus", {files}, "--run", "rs.main"]\n'
                   '[vision]\nrequest_endpoint = "tcp://127.0.0.1:0"\nresponse_endpoint = "tcp://127.0.0.1:0"\n')
    proc = run("demo", "--config", str(cfg), "--out", str(tmp_path / "runs"), "--no-analyze", cwd=tmp_path,
               timeout=150)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    (run_dir,) = (tmp_path / "runs").iterdir()
    result = json.loads((run_dir / "focus.json").read_text())
    assert result["peak_offset_mm"] == pytest.approx(20.0, abs=2.0), result  # the default cell's focal plane
    sim_log = (run_dir / "logs").glob("sim*")
    assert any("vport=1234" in p.read_text() for p in sim_log), "the sim ran the V+ server"
