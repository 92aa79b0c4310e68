"""``aioadept sim --vplus`` with files that are not what the user meant: one line naming the file and exit 2, or
the load problems with a closing count (the last line before the program's own output), and ``--strict`` refusing
to serve. Real child processes; nothing binds a port in these cases."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BROKEN = ".PROGRAM a()\n  x =\n  TYPE \"hi\"\n  y = 1 +\n.END\n"


def sim(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "aioadept", "sim", "--state-endpoint", "none", *argv], cwd=cwd,
                          capture_output=True, text=True, timeout=30)


@pytest.mark.timeout(40)
def test_a_missing_file_is_one_line_naming_it(tmp_path):
    res = sim("--vplus", "nope.V2", "--run", "a", cwd=tmp_path)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == ["aioadept sim: --vplus nope.V2: No such file or directory"]


@pytest.mark.timeout(40)
def test_a_file_with_no_program_is_one_line_not_a_problem_per_line(tmp_path):
    res = sim("--vplus", str(ROOT / "README.md"), "--run", "a", cwd=tmp_path)
    assert res.returncode == 2
    (line,) = res.stderr.strip().splitlines()
    assert "README.md: no .PROGRAM in it" in line


@pytest.mark.timeout(40)
def test_load_problems_end_with_a_count_and_strict_refuses_to_serve(tmp_path):
    (tmp_path / "bad.V2").write_text(BROKEN)
    res = sim("--vplus", "bad.V2", "--run", "a", "--strict", cwd=tmp_path)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert [ln.split(":")[1:3] for ln in lines[:2]] == [[" bad.V2", "2"], [" bad.V2", "4"]]
    assert "2 line(s) did not load (--strict: not serving)" in lines[-1]
    assert "aioadept vplus check bad.V2" in lines[-1]
    assert "READY" not in res.stdout


@pytest.mark.timeout(40)
def test_many_problems_are_capped_with_how_many_more(tmp_path):
    body = "".join(f"  x{i} =\n" for i in range(50))
    (tmp_path / "many.V2").write_text(f".PROGRAM a()\n{body}.END\n")
    res = sim("--vplus", "many.V2", "--run", "a", "--strict", cwd=tmp_path)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 21
    assert "... and 30 more; 50 line(s) did not load" in lines[-1]
