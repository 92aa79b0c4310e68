"""``make bench`` ends with one verdict table (benchmarks/run_all.py).

The runner is driven here on small fake benchmarks (one with verdicts that pass and miss, one with no verdicts, one
that crashes, one that prints no JSON) and on one real benchmark with the fewest iterations. No figure is asserted:
speed is measured in benchmarks/, never in tests.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RUNNER = ROOT / "benchmarks" / "run_all.py"

GOOD = """import json
print(json.dumps({"x": 1, "verdicts": [
    {"name": "fast path p50", "figure": 110.0, "baseline": 100.0, "unit": "us", "ratio": 1.1,
     "goal": "ratio <= 1.3", "pass": True},
    {"name": "slow path p50", "figure": 200.0, "baseline": 100.0, "unit": "us", "ratio": 2.0,
     "goal": "ratio <= 1.3", "pass": False},
    {"name": "informative", "figure": 5.0, "baseline": 4.0, "unit": "ms", "ratio": 1.25, "goal": None,
     "pass": None}]}, indent=2))
"""
NO_VERDICTS = 'import json\nprint(json.dumps({"p50_us": 12.0}, indent=2))\n'
CRASH = 'raise SystemExit("boom")\n'
NO_JSON = 'print("hello")\n'


def _run(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(RUNNER), *args], cwd=cwd, capture_output=True, text=True, timeout=120)


@pytest.fixture
def fakes(tmp_path: Path) -> Path:
    d = tmp_path / "benchmarks"
    d.mkdir()
    (d / "bench_a_good.py").write_text(GOOD)
    (d / "bench_b_plain.py").write_text(NO_VERDICTS)
    (d / "verdicts.py").write_text("raise SystemExit('not a benchmark: never run')\n")
    return d


@pytest.mark.timeout(120)
def test_one_table_with_pass_fail_and_no_goal_rows_and_the_json_kept(fakes: Path, tmp_path: Path) -> None:
    res = _run("--dir", str(fakes), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    out = res.stdout
    assert out.count("┏") == 1                      # one table
    for text in ("bench_a_good", "fast path p50", "110 us", "100 us", "1.1", "ratio <= 1.3", "pass",
                 "slow path p50", "missed", "informative", "bench_b_plain", "no goal stated"):
        assert text in out, text
    assert "FAIL" not in out and "CRASHED" not in out  # a goal missed is not a crash
    assert "1 goals met, 1 missed, 2 without a stated goal, 0 benchmarks crashed" in out
    # The JSON is kept, not printed.
    assert json.loads((tmp_path / "out" / "bench_b_plain.json").read_text()) == {"p50_us": 12.0}
    assert '"p50_us"' not in out
    # --strict: a missed goal is a failure.
    assert _run("--dir", str(fakes), "--out", str(tmp_path / "o2"), "--strict", cwd=tmp_path).returncode == 1


@pytest.mark.timeout(120)
def test_a_crashing_benchmark_or_one_without_json_is_a_failed_row_and_exit_1(fakes: Path, tmp_path: Path) -> None:
    (fakes / "bench_c_crash.py").write_text(CRASH)
    (fakes / "bench_d_text.py").write_text(NO_JSON)
    res = _run("--dir", str(fakes), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert res.returncode == 1
    assert "crashed: exit status 1" in res.stdout and "crashed: printed no JSON object" in res.stdout
    assert res.stdout.count("CRASHED") == 2 and "missed" in res.stdout  # the two kinds kept apart
    assert "2 benchmarks crashed" in res.stdout
    assert "fast path p50" in res.stdout          # the others are still in the table


def test_an_unknown_benchmark_name_is_one_line_and_exit_2(fakes: Path, tmp_path: Path) -> None:
    res = _run("--dir", str(fakes), "--only", "bench_nope", cwd=tmp_path)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [
        f"run_all: no benchmark named bench_nope in {fakes} (there are: bench_a_good, bench_b_plain)"]


@pytest.mark.timeout(120)
def test_a_real_benchmark_in_quick_mode_gives_its_verdict(tmp_path: Path) -> None:
    res = _run("--quick", "--only", "bench_bus", "--out", str(tmp_path / "out"), cwd=ROOT)
    assert res.returncode == 0, res.stderr
    data = json.loads((tmp_path / "out" / "bench_bus.json").read_text())
    # ZeroMQ's Communicator+Responder vs raw pyzmq, and (with the [zenoh] extra) the same pair over Zenoh vs ZeroMQ
    # plus the raw Zenoh floor against it (no goal: it says how much of the Zenoh figure any asyncio code pays),
    # unpinned and, on a machine with two CPUs, pinned: the goal is judged on the pinned pair only.
    verdicts = data["verdicts"]
    pinned = data["pinned_rounds"]
    assert len(verdicts) == ((7 if pinned else 4) if data["eclipse_zenoh"] else 1)
    for v in verdicts:
        assert set(v) == {"name", "figure", "baseline", "unit", "ratio", "goal", "pass"}
        assert v["figure"] > 0 and v["baseline"] > 0
    assert verdicts[0]["goal"] == "ratio <= 1.3" and isinstance(verdicts[0]["pass"], bool)
    assert "Communicator+Responder" in res.stdout
    if data["eclipse_zenoh"]:
        judged = [v for v in verdicts[1:] if v["goal"] is not None]
        assert len(judged) == 1 and judged[0]["goal"] == "ratio <= 1.3" and isinstance(judged[0]["pass"], bool)
        assert "over Zenoh vs over ZeroMQ" in judged[0]["name"]
        assert ("pinned" in judged[0]["name"]) == pinned
        floors = [v for v in verdicts[1:] if "floor" in v["name"]]
        assert len(floors) == (2 if pinned else 1)
        # Zenoh queries (Communicator(queries=True)) are measured beside publications, without a goal.
        queries = [v for v in verdicts[1:] if "queries" in v["name"]]
        assert len(queries) == (2 if pinned else 1) and all(v["goal"] is None for v in queries)
        assert data["communicator_responder_noop_zenoh_queries"]["n"] == 200
        assert all(v["goal"] is None and v["pass"] is None for v in floors)
        assert data["raw_zenoh_asyncio_pingpong"]["n"] == 200
        if pinned:
            assert data["raw_zenoh_asyncio_pingpong_pinned"]["n"] == 200


@pytest.mark.parametrize("name", ["bench_bus", "bench_client", "bench_load", "bench_safety", "bench_sigint",
                                  "bench_sim", "bench_statestream", "bench_vision", "bench_vplus",
                                  "bench_focus_sweep", "bench_multi_cell"])
def test_each_benchmark_puts_the_standard_verdicts_in_its_json(name: str) -> None:
    # A benchmark without the list still runs: the table shows it as "no goal stated".
    assert '"verdicts"' in (ROOT / "benchmarks" / f"{name}.py").read_text(encoding="utf-8")


@pytest.mark.timeout(240)
def test_the_node_and_pipelined_verdicts_come_from_interleaved_samples(tmp_path: Path) -> None:
    """bench_vision's node-vs-raw and bench_client's pipelined verdicts are each the median of ratios taken pair by
    pair with the baseline, interleaved: measured kind after kind, a drifting machine swings a ratio across its goal."""
    import statistics

    res = _run("--quick", "--only", "bench_vision", "--only", "bench_client", "--out", str(tmp_path / "out"),
               cwd=ROOT)
    assert "CRASHED" not in res.stdout, res.stdout + res.stderr
    vision = json.loads((tmp_path / "out" / "bench_vision.json").read_text())
    il = vision["latency_interleaved"]
    assert len(il["ratio_p50_per_round"]) == il["rounds"] >= 1
    (node,) = [v for v in vision["verdicts"] if v["name"].startswith("vision node request->response")]
    assert "interleaved" in node["name"]
    assert node["ratio"] == pytest.approx(statistics.median(il["ratio_p50_per_round"]), abs=1e-3)
    assert node["figure"] == il["p50_us"]["node_auto"] and node["baseline"] == il["p50_us"]["raw_async"]
    client = json.loads((tmp_path / "out" / "bench_client.json").read_text())
    (tp,) = [v for v in client["verdicts"] if v["name"].startswith("pipelined throughput")]
    size = tp["name"].split("batches of ")[1].split()[0]
    pipe = client["pipelined"][size]
    assert pipe["pairs"] >= 30 and tp["ratio"] == pytest.approx(pipe["ratio_median_of_pairs"]["throughput"], abs=1e-3)
