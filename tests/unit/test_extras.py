"""Packaging: a user who only drives a robot needs none of the [vision] and [analysis] extras.

Each test runs a fresh interpreter with a meta-path hook that makes OpenCV, SciPy and Matplotlib uninstallable, as
in a ``pip install aioadept`` without extras; nothing of the real environment is changed.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

BLOCK = textwrap.dedent("""
    import importlib.abc, sys

    class Block(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {"cv2", "scipy", "matplotlib"}:
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)

    sys.meta_path.insert(0, Block())
""")


def run(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", BLOCK + textwrap.dedent(code)], capture_output=True, text=True,
                          timeout=60)


@pytest.mark.timeout(60)
def test_the_core_imports_and_a_client_is_made_without_the_extras():
    proc = run("""
        import aioadept, aioadept.client, aioadept.protocol, aioadept.sim, aioadept.sim.server, aioadept.bus
        import aioadept.testing, aioadept.robots.viper_s850, aioadept.cli
        from aioadept.client import RobotClient
        robot = RobotClient("127.0.0.1", 1234)
        print(type(robot).__name__, sorted(m for m in sys.modules if m.split(".")[0] in {"cv2", "scipy", "matplotlib"}))
    """)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "RobotClient []"


@pytest.mark.timeout(60)
@pytest.mark.parametrize("command", ["sim", "send", "focus", "demo", "analyze", "vision"])
def test_every_subcommands_help_works_without_the_extras(command):
    proc = run(f"""
        from aioadept.cli import main
        try:
            main([{command!r}, "--help"])
        except SystemExit as exc:
            sys.exit(exc.code)
    """)
    assert proc.returncode == 0, proc.stderr
    assert "usage: aioadept " + command in proc.stdout


@pytest.mark.timeout(60)
def test_a_command_that_needs_an_extra_says_which_in_one_line(tmp_path):
    proc = run(f"""
        from aioadept.cli import main
        sys.exit(main(["vision", "--figures", {str(tmp_path / "figs")!r}]))
    """)
    assert proc.returncode == 2
    assert proc.stderr.strip() == ("aioadept vision: needs the 'vision' extra (cv2 is not installed): "
                                   "pip install 'aioadept[vision]'")
