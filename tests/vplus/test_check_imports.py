"""``aioadept vplus check`` loads the V+ front end only: not numpy, asyncio or the emulator's run time, whose
imports were most of its time (benchmarks/bench_vplus_check.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_checking_files_imports_neither_numpy_nor_asyncio_nor_the_emulator():
    code = ("import sys\n"
            "from aioadept.cli import main\n"
            "try:\n"
            "    rc = main(['vplus', 'check', *sys.argv[1:]])\n"
            "except SystemExit as e:\n"
            "    rc = e.code\n"
            "print('exit', rc)\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'asyncio', 'pygls')\n"
            "             or m in ('aioadept.vplus.runtime', 'aioadept.vplus.emulator', 'aioadept.geometry')))\n")
    files = [str(ROOT / "vplus" / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2", "rsstate.V2")]
    r = subprocess.run([sys.executable, "-c", code, *files], capture_output=True, text=True, timeout=60)
    assert r.stdout.splitlines()[-2:] == ["exit 0", "[]"], (r.stdout, r.stderr)
