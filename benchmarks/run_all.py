"""Run every benchmark, keep its JSON, and end with one verdict table (``make bench``).

    .venv/bin/python benchmarks/run_all.py [--quick] [--only NAME ...] [--out DIR] [--strict]

Each ``benchmarks/bench_*.py`` runs as its own process, one after another (the machine is shared: running them at
once would measure each other). Its JSON goes to ``OUT/NAME.json`` (default ``runs/bench-YYYYmmdd-HHMMSS/``, so the
full figures are kept but not printed) and its standard ``"verdicts"`` list (``benchmarks/verdicts.py``) becomes
rows of the table: the figure, its baseline measured in the same run, the ratio, the goal and whether this run met
it ("pass", or "missed": the benchmark ran and the goal was not met). A benchmark without verdicts is shown as
"no goal stated"; one that crashes, times out or prints no JSON as "CRASHED" (it gave no result at all).

``--quick`` runs each known benchmark with few iterations: a smoke run of the whole chain, whose figures are noisy.
Exit status: 0 when every benchmark ran (goals missed are in the table; ``--strict`` makes them exit 1 too), 1 when
a benchmark crashed, 2 on bad usage.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

HERE = Path(__file__).resolve().parent

# Few iterations per benchmark for --quick; a benchmark not listed here runs with its defaults.
QUICK_ARGS: dict[str, list[str]] = {
    "bench_bridge": ["--n", "100", "--blocks", "2", "--warmup", "20", "--stops", "20", "--names", "5000",
                     "--name-rounds", "5"],
    "bench_bus": ["--n", "200", "--warmup", "50", "--rounds", "1"],
    "bench_client": ["--quick"],
    "bench_focus_sweep": ["--rounds", "1"],
    "bench_locate": ["--frames", "5"],
    "bench_multi_cell": ["--rounds", "1", "--restarts", "2"],
    "bench_load": ["--clients", "5", "--sim-seconds", "0.5", "--vision-rates", "5,20", "--vision-seconds", "1",
                   "--idle-seconds", "0.5"],
    "bench_safety": ["--trials", "3"],
    "bench_sim": ["--messages", "300", "--warmup", "30", "--clients", "1,5", "--rounds", "1"],
    "bench_sigint": ["--rounds", "2"],
    "bench_statestream": ["--quick"],
    "bench_vision": ["--frames", "20", "--n", "100", "--warmup", "20", "--rounds", "1", "--verdict-rounds", "1"],
    "bench_vplus": ["--quick"],
    "bench_world": ["--rounds", "20"],
    "bench_pickplace": ["--parts", "10"],
}


def parse_json(stdout: str) -> dict[str, Any] | None:
    """The benchmark's JSON object: all of stdout, or from its first line that opens an object."""
    try:
        out = json.loads(stdout)
    except ValueError:
        lines = stdout.splitlines()
        starts = [i for i, line in enumerate(lines) if line.startswith("{")]
        for i in starts:
            try:
                out = json.loads("\n".join(lines[i:]))
                break
            except ValueError:
                continue
        else:
            return None
    return out if isinstance(out, dict) else None


def run_one(path: Path, args: list[str], timeout_s: float) -> dict[str, Any]:
    """Run one benchmark; its stderr goes to ours (progress, warnings), its stdout is parsed."""
    t0 = time.monotonic()
    try:
        res = subprocess.run([sys.executable, str(path), *args], stdout=subprocess.PIPE, text=True,
                             timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return {"status": f"crashed: no result within {timeout_s:g} s", "seconds": time.monotonic() - t0}
    out: dict[str, Any] = {"seconds": time.monotonic() - t0, "stdout": res.stdout}
    if res.returncode != 0:
        out["status"] = f"crashed: exit status {res.returncode}"
        return out
    data = parse_json(res.stdout)
    if data is None:
        out["status"] = "crashed: printed no JSON object"
        return out
    out.update(status="ok", data=data)
    return out


def rows_of(name: str, result: dict[str, Any]) -> list[dict[str, Any]]:
    """Table rows of one benchmark: its verdicts, or one row saying why there are none."""
    if result["status"] != "ok":
        return [{"bench": name, "name": result["status"], "kind": "failed"}]
    verdicts = result["data"].get("verdicts")
    if not isinstance(verdicts, list) or not verdicts:
        return [{"bench": name, "name": "(no verdicts in its JSON)", "kind": "none"}]
    rows = []
    for v in verdicts:
        if not isinstance(v, dict):
            continue
        kind = "none" if v.get("goal") is None or v.get("pass") is None else ("pass" if v["pass"] else "miss")
        rows.append({"bench": name, **v, "kind": kind})
    return rows or [{"bench": name, "name": "(no verdicts in its JSON)", "kind": "none"}]


def _fmt(x: Any, unit: str = "") -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        x = f"{x:.3g}" if abs(x) < 1000 else f"{x:,.0f}"
    return f"{x} {unit}".strip()


RESULT_TEXT = {"pass": "[green]pass[/]", "miss": "[yellow]missed[/]", "none": "[dim]no goal stated[/]",
               "failed": "[bold red]CRASHED[/]"}
"""The result column: a goal met or missed (the benchmark ran), no goal, or no result at all (crashed)."""


def table(rows: list[dict[str, Any]], title: str) -> Table:
    t = Table(title=title, show_lines=False)
    for col, kw in [("benchmark", {}), ("measure", {"overflow": "fold"}), ("figure", {"justify": "right"}),
                    ("baseline", {"justify": "right"}), ("ratio", {"justify": "right"}), ("goal", {}),
                    ("result", {})]:
        t.add_column(col, **kw)
    last = None
    for r in rows:
        unit = r.get("unit") or ""
        t.add_row("" if r["bench"] == last else r["bench"], r.get("name", ""), _fmt(r.get("figure"), unit),
                  _fmt(r.get("baseline"), unit), _fmt(r.get("ratio")), r.get("goal") or "-", RESULT_TEXT[r["kind"]])
        last = r["bench"]
    return t


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="few iterations per benchmark (a smoke run)")
    ap.add_argument("--only", action="append", metavar="NAME", help="run only this benchmark (repeatable), "
                    "e.g. --only bench_bus")
    ap.add_argument("--dir", type=Path, default=HERE, help=argparse.SUPPRESS)  # tests point it at fake benchmarks
    ap.add_argument("--out", type=Path, help="folder for each benchmark's JSON (default runs/bench-TIMESTAMP)")
    ap.add_argument("--timeout", type=float, default=900.0, help="per benchmark, s (default 900)")
    ap.add_argument("--strict", action="store_true", help="exit 1 when a stated goal is missed")
    args = ap.parse_args(argv)

    benches = sorted(args.dir.glob("bench_*.py"))
    if args.only:
        wanted = {n.removesuffix(".py") for n in args.only}
        unknown = wanted - {p.stem for p in benches}
        if unknown:
            print(f"run_all: no benchmark named {', '.join(sorted(unknown))} in {args.dir} "
                  f"(there are: {', '.join(p.stem for p in benches)})", file=sys.stderr)
            return 2
        benches = [p for p in benches if p.stem in wanted]
    if not benches:
        print(f"run_all: no bench_*.py in {args.dir}", file=sys.stderr)
        return 2
    out_dir = args.out or Path("runs") / _dt.datetime.now().strftime("bench-%Y%m%d-%H%M%S")
    out_dir.mkdir(parents=True, exist_ok=True)

    err = Console(stderr=True)
    rows: list[dict[str, Any]] = []
    for i, path in enumerate(benches, 1):
        extra = QUICK_ARGS.get(path.stem, []) if args.quick else []
        err.print(f"[bold]\\[{i}/{len(benches)}] {path.stem}[/] {' '.join(extra)}")
        res = run_one(path, extra, args.timeout)
        if res["status"] == "ok":
            (out_dir / f"{path.stem}.json").write_text(json.dumps(res["data"], indent=2) + "\n", encoding="utf-8")
        elif res.get("stdout"):
            (out_dir / f"{path.stem}.stdout.txt").write_text(res["stdout"], encoding="utf-8")
        err.print(f"    {res['status']} in {res['seconds']:.1f} s")
        rows += rows_of(path.stem, res)

    # A pipe (make bench | tee) gets a wide table, not rich's 80 columns.
    console = Console() if sys.stdout.isatty() else Console(width=180)
    title = "Benchmarks" + (" (--quick: smoke run, noisy figures)" if args.quick else "")
    console.print(table(rows, title))
    n = {k: sum(r["kind"] == k for r in rows) for k in RESULT_TEXT}
    console.print(f"{n['pass']} goals met, {n['miss']} missed, {n['none']} without a stated goal, "
                  f"{n['failed']} benchmarks crashed. Full JSON: {out_dir}/")
    if n["failed"]:
        return 1
    return 1 if args.strict and n["miss"] else 0


if __name__ == "__main__":
    sys.exit(main())
