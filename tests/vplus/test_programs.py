"""The folder of V+ programs in the style of public teaching and pick-and-place code (examples/vplus/cell/,
"Done when"): each loads with no problem (no unsupported word) and runs on the shared robot model, and does what
it is for. The entry program of each file is named after the file."""

from __future__ import annotations

from pathlib import Path

import pytest

from aioadept.robots import viper_s850 as kin
from aioadept.vplus import Emulator

FOLDER = Path(__file__).resolve().parents[2] / "examples" / "vplus" / "cell"
FILES = sorted(FOLDER.glob("*.V2"))


def run(path: Path, tmp_path: Path) -> Emulator:
    emu = Emulator.load(path, strict=True, disk_dir=tmp_path / "disk")
    emu.call(path.stem, max_time_s=600.0)
    return emu


def test_the_folder_holds_the_programs():
    assert {p.stem for p in FILES} >= {"pallet", "cyclelog", "configs", "teach", "feeder"}


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_each_program_loads_without_problems_and_runs_to_its_end(path, tmp_path):
    emu = run(path, tmp_path)
    assert not emu.problems
    assert emu.console and emu.console[-1].startswith(f"[0] {path.stem}")
    assert not any("*" in line and "Error" in line for line in emu.console)


def test_pallet_places_twelve_parts_and_ends_at_rest_with_the_hand_open(tmp_path):
    emu = run(FOLDER / "pallet.V2", tmp_path)
    ctl = emu.controller
    assert emu.globals["pal.done"] == 12
    assert not ctl.trajectory.in_motion(emu.time_s) and ctl.io.hand_state(emu.time_s) in ("open", "opening")
    # the last part went to the far corner: the arm departed 80 mm, then 100 mm more, straight up from it
    end = ctl.here_at(emu.time_s)
    assert (end.x, end.y, end.z) == pytest.approx((420 + 3 * 50, -120 + 2 * 60, 120 + 80 + 100), abs=1e-3)


def test_cyclelog_writes_reads_and_lists_its_log(tmp_path):
    emu = run(FOLDER / "cyclelog.V2", tmp_path)
    lines = (tmp_path / "disk" / "cycles.log").read_bytes().split(b"\r\n")
    assert [ln.split(b" at ")[0] for ln in lines[:-1]] == [b"cycle %d" % i for i in range(1, 6)] and lines[-1] == b""
    g = emu.globals
    assert g["log.n"] == 5 and g["$log.last"].startswith("cycle 5 at ") and g["log.eof"] < 0 and g["log.files"] == 1


def test_configs_flips_the_wrist_and_unwinds_joint_6(tmp_path):
    g = run(FOLDER / "configs.V2", tmp_path).globals
    assert g["cfg.flipj5"] < 0 < g["cfg.backj5"] and g["cfg.j6"] == pytest.approx(-60.0, abs=1e-3)


def test_teach_replays_the_taught_points_with_the_tool(tmp_path):
    emu = run(FOLDER / "teach.V2", tmp_path)
    tip = kin.forward((0, -90, 180, 0, 90, 0))
    assert emu.globals["$tch.line"][0].startswith(f"{tip.x:.1f},{tip.y:.1f},{tip.z - 120:.1f}")
    assert emu.globals["tch.dz"] == pytest.approx(-120.0, abs=1e-3)
    assert emu.controller.joints_at(emu.time_s) == pytest.approx((0, -90, 180, 0, 90, 0), abs=1e-3)


def test_feeder_takes_every_part_the_other_task_presents(tmp_path):
    g = run(FOLDER / "feeder.V2", tmp_path).globals
    assert g["fd.count"] == 6 and g["fd.mask"] == 7 and g["fd.caught"] == 1 and g["$fd.name"] == "feeder"
