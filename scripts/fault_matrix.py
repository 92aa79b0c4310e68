#!/usr/bin/env python3
"""Run the fault matrix and print its table: case -> result -> what was observed.

    .venv/bin/python scripts/fault_matrix.py                      # rich table on the terminal
    .venv/bin/python scripts/fault_matrix.py --markdown out.md    # also the Markdown table (docs/faults.md)
    .venv/bin/python scripts/fault_matrix.py --json out.json      # also the records, figures included
    .venv/bin/python scripts/fault_matrix.py -- -k toxiproxy      # anything after -- goes to pytest

It runs ``pytest tests/integration/test_fault_matrix.py`` in a subprocess with ``--junitxml``; each test names its
case and records its outcome as JUnit properties (see the module's ``outcome`` fixture), so the table shows what
the run actually observed, skipped cases with their reason and failed ones with pytest's message. Exit code: pytest's
(0 when every case passed or was skipped).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.table import Table

ROOT = Path(__file__).resolve().parent.parent
MODULE = "tests/integration/test_fault_matrix.py"
STYLE = {"passed": "green", "failed": "bold red", "skipped": "yellow", "error": "bold red"}


def run_pytest(extra: list[str], xml_path: Path) -> int:
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", MODULE, f"--junitxml={xml_path}",
           "-rs", *extra]
    print("$", " ".join(cmd), file=sys.stderr)
    return subprocess.run(cmd, cwd=ROOT).returncode


def records(xml_path: Path) -> list[dict]:
    """One dict per test case: name, case, result, outcome, time_s, figures."""
    out = []
    for tc in ET.parse(xml_path).getroot().iter("testcase"):
        props = {p.get("name"): p.get("value") for p in tc.iter("property")}
        result, text = "passed", props.pop("outcome", "")
        for tag in ("failure", "error", "skipped"):
            el = tc.find(tag)
            if el is not None:
                result = {"failure": "failed"}.get(tag, tag)
                message = (el.get("message") or el.text or "").strip()
                text = message.splitlines()[0] if message else tag
                break
        out.append({"test": tc.get("name"), "case": props.pop("case", tc.get("name")), "result": result,
                    "outcome": text, "time_s": round(float(tc.get("time") or 0), 2), "figures": props})
    return out


def print_table(rows: list[dict], total_s: float) -> None:
    table = Table(title=f"Fault matrix ({len(rows)} cases, {total_s:.1f} s of tests)", show_lines=True)
    table.add_column("case", ratio=2)
    table.add_column("result", no_wrap=True)
    table.add_column("outcome", ratio=4, overflow="fold")
    table.add_column("s", justify="right", no_wrap=True)
    for r in rows:
        # escape: outcomes quote ID lists and parameters in [brackets], which rich would take for markup
        table.add_row(escape(r["case"]), f"[{STYLE[r['result']]}]{r['result']}[/]", escape(r["outcome"]),
                      f"{r['time_s']:.2f}")
    Console(width=max(120, Console().width)).print(table)


def markdown(rows: list[dict]) -> str:
    def cell(text: str) -> str:
        return text.replace("|", "\\|").replace("\n", " ")
    lines = ["| case | result | outcome | s |", "|---|---|---|---:|"]
    lines += [f"| {cell(r['case'])} | {r['result']} | {cell(r['outcome'])} | {r['time_s']:.2f} |" for r in rows]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    extra: list[str] = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1:]
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--markdown", type=Path, metavar="FILE", help="write the table as Markdown")
    p.add_argument("--json", type=Path, metavar="FILE", help="write the records as JSON")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        xml_path = Path(tmp) / "fault_matrix.xml"
        rc = run_pytest(extra, xml_path)
        if not xml_path.exists():
            print("fault_matrix: pytest wrote no report", file=sys.stderr)
            return rc or 1
        rows = records(xml_path)
    print_table(rows, sum(r["time_s"] for r in rows))
    if args.markdown:
        args.markdown.write_text(markdown(rows))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2) + "\n")
    return rc


if __name__ == "__main__":
    sys.exit(main())
