"""Every python code block of the README runs as printed (doctest-style extraction), and the client example shows
what the text promises: real server times from the simulator and a `refused:` line for an unreachable target."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[2] / "README.md"


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), re.S)


@pytest.mark.timeout(60)
def test_the_readme_has_python_blocks():
    assert _python_blocks()


@pytest.mark.timeout(60)
@pytest.mark.parametrize("index", range(len(_python_blocks())))
def test_each_python_block_runs(index):
    code = _python_blocks()[index]
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=50)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.timeout(60)
def test_the_client_example_runs_against_the_simulator_and_prints_a_refusal():
    text = README.read_text()
    code = re.search(r"```python\n(.*?)```", text[text.index("## Using the client"):], re.S).group(1)
    assert "ScriptedServer" not in code
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=50)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    refused = [ln for ln in lines if ln.startswith("refused:")]
    assert refused and refused[0].split()[1] == "-610", proc.stdout  # location out of range
    (brk,) = [ln for ln in lines if " break done " in ln]
    server_s = float(re.search(r"server (\d+\.\d+) s", brk).group(1))
    assert server_s > 0, brk  # the break waited for a real (simulated) motion


@pytest.mark.timeout(30)
def test_the_readme_states_the_side_effects_of_make_test_and_analyze():
    text = " ".join(README.read_text().split())
    assert "toxiproxy (a Go program" in text and "~/.cache/aioadept/bin" in text
    assert "chromium" in text
    assert "`./analysis/`" in text
