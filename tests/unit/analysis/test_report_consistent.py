"""One consistent analysis per folder and a full disk that names what it could not write: a second analysis leaves no figure of the first; a figure that cannot be written is named, never
left empty; an interrupted analysis leaves the previous one as it was."""

from __future__ import annotations

import errno
import json

import pytest

from aioadept.runs import capture
from aioadept.analysis import FIGURES, analyze_runs
from aioadept.analysis.report import ANALYSIS_FILES
from aioadept.errors import AnalysisSaveError
from aioadept.analysis.synthetic import synthetic_recorder


def _run(path):
    rec, params = synthetic_recorder(seed=5, n_steps=5)
    return rec.save(path, metadata=params)


def _outputs(run_dir) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in run_dir.iterdir() if p.name in ANALYSIS_FILES}


def _fail_writes(monkeypatch, predicate, exc_factory) -> None:
    """Make run-folder writes whose file name matches ``predicate`` fail (capture's one place bytes go to disk)."""
    real = capture._open_for_write

    def open_for_write(path, binary):
        if predicate(path.name):
            raise exc_factory()
        return real(path, binary)

    monkeypatch.setattr(capture, "_open_for_write", open_for_write)


def test_a_second_analysis_leaves_no_figure_of_the_first(tmp_path):
    run_dir = _run(tmp_path / "run")
    analyze_runs([run_dir])
    assert set(FIGURES.values()) <= set(_outputs(run_dir))
    summary = analyze_runs([run_dir], plots=False)
    left = sorted(_outputs(run_dir))
    assert left == ["iterations.csv", "summary.json"], left  # today: the six figures of the first stay beside it
    info = json.loads((run_dir / "summary.json").read_text())
    assert sorted(info["files"].values()) == left and info["not_written"] == {}
    assert sorted(p.name for p in summary.files.values()) == left
    assert not [p for p in run_dir.iterdir() if p.name.startswith(".")], "a staging folder was left behind"


def test_a_figure_the_disk_cannot_take_is_named_and_never_left_empty(tmp_path, monkeypatch):
    run_dir = _run(tmp_path / "run")
    _fail_writes(monkeypatch, lambda name: "fig09" in name, lambda: OSError(errno.ENOSPC, "No space left on device"))
    with pytest.raises(AnalysisSaveError) as caught:
        analyze_runs([run_dir])
    err = caught.value
    assert err.not_written == {"fig09_sharpness.png": "No space left on device"}
    assert "fig09_sharpness.png (No space left on device)" in str(err)
    names = _outputs(run_dir)
    assert "fig09_sharpness.png" not in names  # not there rather than empty
    assert set(FIGURES.values()) - {"fig09_sharpness.png"} <= set(names)
    assert all(data for data in names.values()), [n for n, d in names.items() if not d]
    info = json.loads(names["summary.json"])
    assert info["not_written"] == {"fig09_sharpness.png": "No space left on device"}
    assert "sharpness" not in info["files"]
    assert err.summary is not None and err.summary.not_written == err.not_written


def test_an_interrupted_analysis_leaves_the_previous_one_as_it_was(tmp_path, monkeypatch):
    run_dir = _run(tmp_path / "run")
    analyze_runs([run_dir])
    before = _outputs(run_dir)
    _fail_writes(monkeypatch, lambda name: "fig11_" in name, KeyboardInterrupt)  # Ctrl-C mid-way through
    with pytest.raises(KeyboardInterrupt):
        analyze_runs([run_dir], plots=True)
    assert _outputs(run_dir) == before
    assert not [p for p in run_dir.iterdir() if p.name.startswith(".")], "a staging folder was left behind"


def test_aioadept_analyze_names_what_it_could_not_write_and_says_one_line_on_ctrl_c(tmp_path, monkeypatch, capsys):
    from aioadept.cli.analyze import main

    run_dir = _run(tmp_path / "run")
    _fail_writes(monkeypatch, lambda name: "fig10" in name, lambda: OSError(errno.ENOSPC, "No space left on device"))
    assert main([str(run_dir), "--no-rrd"]) == 4
    err = capsys.readouterr().err.splitlines()
    assert err == [f"aioadept analyze: analysis in {run_dir}: not written: fig10_gantt.png (No space left on device)"]
    _fail_writes(monkeypatch, lambda name: "summary" in name, KeyboardInterrupt)
    before = _outputs(run_dir)
    assert main([str(run_dir), "--no-rrd"]) == 130
    err = capsys.readouterr().err.splitlines()
    assert err == ["aioadept analyze: interrupted: the analysis was not written (a previous one stays as it was)"]
    assert _outputs(run_dir) == before


def test_the_default_analysis_folder_is_ignored_by_git():
    # `aioadept analyze RUN RUN...` writes ./analysis/ into the current folder: in a clone, never a file to commit.
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    ignored = subprocess.run(["git", "check-ignore", "-q", "analysis/summary.json"], cwd=root)
    assert ignored.returncode == 0, "analysis/ is not in .gitignore"
    kept = subprocess.run(["git", "check-ignore", "-q", "src/aioadept/analysis/report.py"], cwd=root)
    assert kept.returncode == 1, "the analysis package itself must not be ignored"


@pytest.mark.parametrize("where", ["inside", "cleanup"])
def test_ctrl_c_inside_the_analysis_or_in_its_cleanup_leaves_no_staging_folder(tmp_path, monkeypatch, where):
    """KeyboardInterrupt lands wherever the signal finds the program: in the analysis, or in the middle of removing
    the staging folder (a half-removed one was left behind so, found by test_demo_outputs under load)."""
    import shutil

    from aioadept.analysis import outputs

    real_rmtree = shutil.rmtree
    calls = []

    def rmtree(path, *a, **kw):
        calls.append(path)
        if where == "cleanup" and len(calls) == 2:  # the cleanup's first attempt is interrupted part way
            real_rmtree(next(iter(sorted(path.iterdir()))), *a, **kw)
            raise KeyboardInterrupt
        return real_rmtree(path, *a, **kw)

    monkeypatch.setattr(outputs.shutil, "rmtree", rmtree)
    with pytest.raises(KeyboardInterrupt):
        with outputs.staging(tmp_path) as stage:
            (stage / "a").mkdir()
            (stage / "a" / "f.png").write_bytes(b"x")
            (stage / "b.csv").write_text("y")
            if where == "inside":
                raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
