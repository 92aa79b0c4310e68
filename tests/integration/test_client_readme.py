"""The README's client example is real: it runs as printed."""

from __future__ import annotations

import asyncio
import re
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[2] / "README.md"


@pytest.mark.timeout(20)
async def test_readme_client_example_runs():
    text = README.read_text()
    section = text[text.index("## Using the client"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    proc = await asyncio.create_subprocess_exec(sys.executable, "-c", code, stdout=asyncio.subprocess.PIPE,
                                                stderr=asyncio.subprocess.PIPE)
    out, err = await proc.communicate()
    assert proc.returncode == 0, err.decode()
    lines = out.decode().splitlines()
    assert [line.split()[1:3] for line in lines[:3]] == [["set_speed", "done"], ["move_rel_tool", "done"],
                                                         ["break", "done"]]
    assert lines[3].startswith("at rest in Pose(")
