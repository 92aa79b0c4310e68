"""The classic Cobra cell (examples/cobra-pickplace.toml) end to end on both backends, the Python sim and the shipped
V+ server on the emulator (``[robot] sim_args = ["--vplus", ...]``): a Cobra s600 SCARA picks 20 parts off the
feeder and places them on the pallet within 1 mm and 1 deg (real sim and vision node processes, the part locator on
the world camera's images, real TCP and ZeroMQ)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from aioadept.apps.cell import new_run_dir
from aioadept.cell.config import CellConfig
from aioadept.robots import model

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "cobra-pickplace.toml"
VPLUS = ["--vplus", *(str(ROOT / "vplus" / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")), "--run", "rs.main"]


@pytest.mark.timeout(240)
@pytest.mark.parametrize("backend", ["python", "vplus"])
def test_a_cobra_places_20_of_20_parts_within_1_mm_and_1_deg(tmp_path, backend):
    from aioadept.cli.pickplace import run

    cfg = CellConfig.from_toml(EXAMPLE)
    assert (cfg.robot.model, cfg.pickplace.parts) == ("cobra-s600", 20)
    cfg.robot.time_scale = 10.0
    if backend == "vplus":
        cfg.robot.sim_args = VPLUS
    cfg.run.out_dir = str(tmp_path / "runs")
    cfg.run.name = "t"
    cfg.run.record = False  # what run.rrd/run.mcap of a Cobra hold: tests/unit/record (a recording here costs ~10 s)
    run_dir = new_run_dir(cfg)
    code = run(cfg, run_dir)
    assert code == 0, (run_dir / "logs" / "vision.log").read_text()[-3000:]
    s = json.loads((run_dir / "summary.json").read_text())
    assert (s["parts_placed"], s["parts_failed"], s["parts_dropped"], s["error"]) == (20, 0, 0, None)
    assert max(s["place_error_mm"]) <= 1.0 and max(s["place_error_deg"]) <= 1.0
    # the sim that served it was the Cobra: the first ack reports its home pose (a Viper's is 480, 0, 710)
    with (run_dir / "robot.csv").open() as f:
        first = next(csv.DictReader(f))
    home = model("cobra-s600").forward(model("cobra-s600").home_deg)
    got = [float(first[f"pose_{k}"]) for k in ("x_mm", "y_mm", "z_mm", "yaw_deg", "pitch_deg", "roll_deg")]
    assert got == pytest.approx(list(home), abs=1e-3)
