"""The tree passes ruff (the project's linter, pinned in the test extra) with the rules pyproject.toml's
[tool.ruff.lint] selects: pyflakes (unused and undefined names), pycodestyle's defaults, bugbear (likely bugs: a
zip() that drops items, a closure reading a loop variable late, a computed default) and McCabe complexity (no
function over 15 branches), with no per-file ignores. Run ``.venv/bin/ruff check src tests benchmarks`` to see the
same findings."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _ruff() -> str | None:
    beside = Path(sys.executable).with_name("ruff")
    return str(beside) if beside.exists() else shutil.which("ruff")


@pytest.mark.timeout(60)
def test_the_tree_passes_ruff() -> None:
    ruff = _ruff()
    if ruff is None:
        pytest.skip("LOUD SKIP: ruff is not installed (it is in the [test] extra and requirements.lock: `make test`)")
    out = subprocess.run([ruff, "check", "--output-format", "concise", "src", "tests", "benchmarks"], cwd=ROOT,
                         capture_output=True, text=True, timeout=50)
    assert out.returncode == 0, out.stdout + out.stderr
