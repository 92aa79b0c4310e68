"""The modules of aioadept.vplus import one another as a DAG (the builtins <-> iodev <-> runtime
circle is gone), and each can be imported first, alone, in a fresh interpreter."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "unit"))
from test_import_rules import cycles, graph, modules  # noqa: E402  (the project's own import graph, read by ast)

VPLUS = sorted(m for m in modules() if m.startswith("aioadept.vplus"))


def test_the_vplus_modules_form_a_dag():
    g = {m: {d for d in deps if d.startswith("aioadept.vplus")} for m, deps in graph().items() if m in VPLUS}
    assert cycles(g) == []
    # the order a reader can take them in: each module after everything it imports
    assert g["aioadept.vplus.iodev"] & {"aioadept.vplus.builtins", "aioadept.vplus.runtime"} == set()
    assert "aioadept.vplus.runtime" not in g["aioadept.vplus.builtins"]


@pytest.mark.timeout(120)
def test_each_vplus_module_imports_first_in_a_fresh_interpreter():
    code = ("import importlib, sys\n"
            "for m in sys.argv[1:]:\n"
            "    for k in [k for k in sys.modules if k.startswith('aioadept')]:\n"
            "        del sys.modules[k]\n"
            "    importlib.import_module(m)\n")
    r = subprocess.run([sys.executable, "-c", code, *VPLUS], capture_output=True, text=True, timeout=100)
    assert r.returncode == 0, r.stderr
