"""The Makefile's venv creation: two makes started at once install once, one after the other.

A fake ``python3`` (``PY=``) stands in for the real one: its ``-m venv DIR`` writes a ``DIR/bin/pip`` that logs its
start and end around a short sleep, so overlapping installs show as interleaved lines and a second install as
more lines. Nothing is downloaded.
"""

from __future__ import annotations

import shutil
import subprocess
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

FAKE_PY = textwrap.dedent("""\
    #!/bin/sh
    # -m venv DIR: a venv whose pip logs start/end of each call around a sleep
    [ "$1" = "-m" ] && [ "$2" = "venv" ] || exit 3
    mkdir -p "$3/bin"
    cat > "$3/bin/pip" <<'PIP'
    #!/bin/sh
    echo "start $$" >> "$(dirname "$0")/../../pip.log"
    sleep 0.3
    echo "end $$" >> "$(dirname "$0")/../../pip.log"
    PIP
    chmod +x "$3/bin/pip"
""")


@pytest.mark.timeout(60)
@pytest.mark.skipif(shutil.which("make") is None or shutil.which("flock") is None,
                    reason="LOUD SKIP: needs make and flock (util-linux) on PATH")
def test_two_makes_at_once_install_the_venv_once(tmp_path: Path) -> None:
    shutil.copy(ROOT / "Makefile", tmp_path / "Makefile")
    (tmp_path / "pyproject.toml").write_text("")
    (tmp_path / "requirements.lock").write_text("")
    fake = tmp_path / "fakepython"
    fake.write_text(FAKE_PY)
    fake.chmod(0o755)
    makes = [subprocess.Popen(["make", "-s", "venv", f"PY={fake}"], cwd=tmp_path, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    for m in makes:
        _, err = m.communicate(timeout=50)
        assert m.returncode == 0, err
    log = (tmp_path / "pip.log").read_text().split()
    events = log[0::2]
    # one install (3 pip calls), each call ending before the next starts
    assert events == ["start", "end"] * 3, log
    assert (tmp_path / ".venv" / ".installed").exists()
