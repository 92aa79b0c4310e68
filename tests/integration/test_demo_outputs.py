"""What ``aioadept demo`` leaves in its run folder when the disk is full or when Ctrl-C comes
during the analysis, with the demo and its nodes as real processes.

The full disk is a real 200 KiB tmpfs, mounted in a mount namespace of its own (``unshare``), so nothing is left
mounted whatever happens to the test; where namespaces are not allowed the test is skipped.
"""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from aioadept.analysis import FIGURES

AIOADEPT = [sys.executable, "-m", "aioadept"]
OUTPUTS = ("focus.json", "robot.csv", "vision.csv", "marks.csv", "run.json", "run.rrd", "run.mcap", "frames/frames.csv",
           *FIGURES.values(), "iterations.csv", "summary.json")
"""Every output of a demo run folder: each is there whole or named as not written."""


def _unshare_prefix() -> list[str] | None:
    """``unshare`` arguments for a private mount namespace where tmpfs can be mounted, or None."""
    if shutil.which("unshare") is None:
        return None
    for prefix in (["unshare", "--mount"], ["unshare", "--user", "--map-root-user", "--mount"]):
        probe = subprocess.run([*prefix, "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt || exit 1"],
                               capture_output=True, timeout=30)
        if probe.returncode == 0:
            return prefix
    return None


@pytest.mark.timeout(150)
def test_a_full_disk_leaves_no_empty_file_and_names_every_output_not_written(tmp_path):
    prefix = _unshare_prefix()
    if prefix is None:
        pytest.skip("cannot mount a tmpfs in a mount namespace here (unshare not permitted)")
    disk = tmp_path / "disk"
    disk.mkdir()
    # Inside the namespace: mount, run the demo, then report what is on the (private) disk as one JSON line.
    listing = textwrap.dedent("""
        import json, os, sys
        root = sys.argv[1]
        files = {}
        for d, _dirs, names in os.walk(root):
            for n in names:
                p = os.path.join(d, n)
                files[os.path.relpath(p, root)] = os.path.getsize(p)
        runs = os.path.join(root, "runs")
        (run,) = os.listdir(runs)
        try:  # the disk may fill before the run's own tables are written: then there is no run.json
            with open(os.path.join(runs, run, "run.json")) as f:
                not_written = json.load(f)["not_written"]
        except FileNotFoundError:
            not_written = None
        print("LISTING " + json.dumps({"run": run, "files": files, "not_written": not_written}))
    """)
    (tmp_path / "listing.py").write_text(listing)
    script = (f'mount -t tmpfs -o size=200k tmpfs "{disk}" || exit 99\n'
              f'"{sys.executable}" -m aioadept demo --fast --out "{disk}/runs"; rc=$?\n'
              f'"{sys.executable}" "{tmp_path / "listing.py"}" "{disk}"\n'
              'echo "DEMO_RC $rc"\n')
    proc = subprocess.run([*prefix, "sh", "-c", script], capture_output=True, text=True, timeout=140)
    lines = proc.stdout.splitlines()
    assert "Traceback" not in proc.stderr, proc.stderr
    data = json.loads(next(ln for ln in lines if ln.startswith("LISTING "))[len("LISTING "):])
    run = f"runs/{data['run']}/"
    files = {name[len(run):]: size for name, size in data["files"].items() if name.startswith(run)}
    not_written = data["not_written"]
    # A write during the run itself that meets the full disk (a node's log line, a frame) never ends the run: the
    # result is printed and every output not written is named (tests/integration/test_node_log_full_disk.py).
    assert not [ln for ln in proc.stderr.splitlines() if ln.startswith("aioadept demo failed:")], proc.stderr[-3000:]
    # Nothing empty or half written under its final name (an empty fig09_sharpness.png or frames.csv, a truncated
    # run.rrd).
    assert not [n for n, size in files.items() if size == 0], files
    assert not [n for n in files if os.path.basename(n).startswith(".")], files
    assert "DEMO_RC 4" in lines, proc.stdout[-2000:] + proc.stderr  # the result printed, exit 4
    assert "inspection-start pose" in proc.stdout, proc.stdout[-2000:]
    # Every output is there or named in the one stderr line, and in run.json when the run's tables made it.
    (line,) = [ln for ln in proc.stderr.splitlines() if "NOT fully saved" in ln]
    analysis = {*FIGURES.values(), "iterations.csv", "summary.json"}
    for name in OUTPUTS:
        named = f" {name} (" in line or (name in analysis and " analysis (" in line)
        assert (name in files) != named, (name, files, line)
    if "run.json" in files:
        assert not_written, "the disk was full: something was not written"
        for name, why in not_written.items():
            assert f"{name} ({why})" in line, (name, line)
        # run.rrd (~140 KiB here) is the first to meet the full disk: it is named, never left cut short.
        assert "run.rrd" in not_written, not_written


@pytest.mark.timeout(150)
def test_a_file_size_limit_leaves_no_cut_short_recording_and_names_it(tmp_path):
    # The same promise where no tmpfs can be mounted: the file-size limit of tests/integration/test_results_kept.py
    # (RLIMIT_FSIZE binds root too; the nodes inherit it). 64 KiB: the tables fit, run.rrd (~240 KiB) does not.
    import resource

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (64 * 1024, 64 * 1024))

    runs = tmp_path / "runs"
    proc = subprocess.run([*AIOADEPT, "demo", "--fast", "--out", str(runs)], capture_output=True, text=True,
                          timeout=140, preexec_fn=limit, stdin=subprocess.DEVNULL)
    assert proc.returncode == 4, proc.stdout[-2000:] + proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    (run_dir,) = runs.iterdir()
    files = {p.relative_to(run_dir).as_posix(): p.stat().st_size for p in run_dir.rglob("*") if p.is_file()}
    assert not [n for n, size in files.items() if size == 0], files
    assert not [n for n in files if Path(n).name.startswith(".")], files
    not_written = json.loads((run_dir / "run.json").read_text())["not_written"]
    (line,) = [ln for ln in proc.stderr.splitlines() if "NOT fully saved" in ln]
    assert "run.rrd" in not_written and "run.rrd" not in files, (not_written, files)
    for name in OUTPUTS:
        assert (name in files) != (name in not_written), (name, files, not_written)
    for name, why in not_written.items():
        assert f"{name} ({why})" in line, (name, line)


@pytest.mark.timeout(150)
def test_an_experiment_run_whose_recording_the_full_disk_cut_short_is_still_analysed(tmp_path):
    # Its tables are whole: the run counts and is analysed; run.rrd is named in its run.json, never left cut short.
    prefix = _unshare_prefix()
    if prefix is None:
        pytest.skip("cannot mount a tmpfs in a mount namespace here (unshare not permitted)")
    disk = tmp_path / "disk"
    disk.mkdir()
    (tmp_path / "listing.py").write_text(textwrap.dedent("""
        import json, os, sys
        root, found = sys.argv[1], {"empty": [], "not_written": {}, "n_runs": None}
        for d, _dirs, names in os.walk(root):
            for n in names:
                p = os.path.join(d, n)
                if os.path.getsize(p) == 0 or n.startswith("."):
                    found["empty"].append(p)
                if n == "run.json":
                    found["not_written"][os.path.basename(d)] = json.load(open(p))["not_written"]
                if n == "summary.json":
                    found["n_runs"] = json.load(open(p))["n_runs"]
                if n == "iterations.csv":
                    found["analysed"] = sorted({ln.split(",")[0] for ln in open(p).read().splitlines()[1:]})
        print("LISTING " + json.dumps(found))
    """))
    script = (f'mount -t tmpfs -o size=200k tmpfs "{disk}" || exit 99\n'
              f'"{sys.executable}" -m aioadept experiment --speeds 25 --delta-z 2 --runs 1 --time-scale 10 '
              f'--out "{disk}/x"; rc=$?\n'
              f'"{sys.executable}" "{tmp_path / "listing.py"}" "{disk}"\n'
              'echo "EXPERIMENT_RC $rc"\n')
    proc = subprocess.run([*prefix, "sh", "-c", script], capture_output=True, text=True, timeout=140)
    lines = proc.stdout.splitlines()
    assert "Traceback" not in proc.stderr, proc.stderr
    found = json.loads(next(ln for ln in lines if ln.startswith("LISTING "))[len("LISTING "):])
    assert found["empty"] == [], found
    # The recording (run.rrd, written during the run) fills the disk first; on a loaded machine the run is slower,
    # its recording larger, and the disk may be full before the run's tables are written too: then the run is not
    # saved whole, and the experiment says so in its last line (exit 1), the result and each table not written in
    # the run's log line, nothing cut short.
    if not found["not_written"]:
        assert any(ln == "EXPERIMENT_RC 1" for ln in lines), proc.stdout[-2000:]
        assert "aioadept experiment: no run was saved whole" in proc.stderr, proc.stderr[-3000:]
        logged = " ".join(proc.stdout.split())  # the log's lines, wrapped by rich
        assert "found the inspection pose" in logged and "(No space left on device)" in logged, proc.stdout[-3000:]
        return
    assert len(found["not_written"]) == 1, (found, proc.stdout[-3000:], proc.stderr[-3000:])
    ((_run, not_written),) = found["not_written"].items()
    assert "run.rrd" in not_written, not_written
    # A run lacking only its recording is analysed: its iterations are in the analysis's table. The summary is
    # written last; on this small a disk it may meet the full disk too (run.mcap, written once run.rrd's space was
    # freed, takes ~23 KiB of it), and is then named as not written, never left cut short.
    # On a loaded machine the analysis's own files may not fit either; they are named as not written (none is left
    # cut short: "empty" above), never missing silently.
    assert not [ln for ln in proc.stderr.splitlines() if ln.startswith("aioadept experiment failed:")], \
        proc.stderr[-3000:]
    assert found.get("analysed") == [_run] or "iterations.csv (No space left on device)" in proc.stderr, \
        (found, proc.stderr[-3000:])
    assert found["n_runs"] == 1 or "summary.json (No space left on device)" in proc.stderr, (found, proc.stderr)
    assert any(ln in ("EXPERIMENT_RC 0", "EXPERIMENT_RC 4") for ln in lines), proc.stdout[-2000:] + proc.stderr


async def _read_until(stream: asyncio.StreamReader, needle: str, seen: list[str], timeout_s: float) -> None:
    async with asyncio.timeout(timeout_s):
        while True:
            raw = await stream.readline()
            if not raw:
                raise AssertionError(f"output ended before {needle!r}:\n{''.join(seen)}")
            seen.append(raw.decode(errors="replace"))
            if needle in seen[-1]:
                return


@pytest.mark.timeout(120)
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGHUP], ids=["SIGINT", "SIGHUP"])
async def test_ctrl_c_during_the_analysis_keeps_the_run_and_says_how_to_redo_it(tmp_path, sig):
    runs = tmp_path / "runs"
    proc = await asyncio.create_subprocess_exec(
        *AIOADEPT, "demo", "--fast", "--no-record", "--out", str(runs), stdin=asyncio.subprocess.DEVNULL,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    seen: list[str] = []
    try:
        assert proc.stdout is not None
        await _read_until(proc.stdout, "run folder:", seen, timeout_s=90)  # the analysis starts right after it
        os.kill(proc.pid, sig)  # SIGHUP: the terminal closed (SIGTERM is handled alike)
        async with asyncio.timeout(30):
            out, err_b = await proc.communicate()
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()
    err = err_b.decode(errors="replace")
    (run_dir,) = runs.iterdir()
    assert proc.returncode == 130, "".join(seen) + out.decode(errors="replace") + err
    assert "Traceback" not in err  # today: a 60-line traceback
    # (An interrupt Python raised inside a garbage-collected object's __del__ prints "Exception ignored" and is
    # raised again by the app when its analysis ends: then the analysis is whole and the line says so.)
    lines = [ln for ln in err.splitlines() if ln.strip() and "interrupted after the run" in ln]
    assert len(lines) == 1 and "kept" in lines[0], err
    # The run is kept whole; the analysis is all or nothing, no staging folder left.
    assert json.loads((run_dir / "focus.json").read_text())["peak_index"] >= 0
    assert (run_dir / "run.json").is_file()
    names = {p.name for p in run_dir.iterdir()}
    assert not [n for n in names if n.startswith(".")], names
    if "summary.json" in names:
        assert "its analysis was written" in lines[0], err
        assert set(FIGURES.values()) <= names
    else:
        assert f"redo it with `aioadept analyze {run_dir}`" in lines[0], err
        assert not names & {*FIGURES.values(), "iterations.csv"}, names
        assert [ln for ln in err.splitlines() if ln.strip()] == lines, err  # one line, nothing else


@pytest.mark.timeout(120)
async def test_ctrl_c_during_the_experiments_analysis_keeps_the_runs_and_says_how_to_redo_it(tmp_path):
    out = tmp_path / "x"
    proc = await asyncio.create_subprocess_exec(
        *AIOADEPT, "experiment", "--speeds", "25", "--delta-z", "2", "--runs", "1", "--time-scale", "10",
        "--no-record", "--out", str(out), stdin=asyncio.subprocess.DEVNULL, stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE)
    try:
        async with asyncio.timeout(90):  # the analysis has begun once its staging folder exists
            while not list((out / "analysis").glob(".analysis.*.tmp")) and proc.returncode is None:
                await asyncio.sleep(0.005)
        if proc.returncode is not None:  # it ended before its analysis began (failed once in a full suite): say how
            _out, err_b = await proc.communicate()
            pytest.fail(f"the experiment exited {proc.returncode} before its analysis began:\n"
                        f"{err_b.decode(errors='replace')[-3000:]}\n{sorted(p.name for p in out.rglob('*'))}")
        os.kill(proc.pid, signal.SIGINT)
        async with asyncio.timeout(30):
            _out, err_b = await proc.communicate()
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()
    err = err_b.decode(errors="replace")
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert len(lines) == 1 and "interrupted during the analysis: the runs are kept" in lines[0], err
    left = sorted(p.name for p in (out / "analysis").iterdir())
    if "summary.json" in left:  # an interrupt swallowed by a __del__ and raised again at the end: whole
        assert "its analysis was written" in lines[0], err
    else:
        assert f"redo it with `aioadept analyze {out} --out {out / 'analysis'}`" in lines[0], err
        assert not left, f"half an analysis was left: {left}"
    (run_json,) = out.rglob("run.json")  # the run is kept
    assert json.loads(run_json.read_text())["not_written"] == {}
