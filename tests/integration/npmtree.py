"""An npm package tree for a test's node script: the folder's package.json, package-lock.json and scripts copied
into build/<name> (git ignores build/) and ``npm ci`` run there, again only when the lock file changed. Where node
or npm is missing, the test is skipped with a warning that names what did not run."""

from __future__ import annotations

import fcntl
import shutil
import subprocess
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def npm_tree(source: Path, name: str, *, what: str) -> Path:
    """The folder build/<name> holding ``source``'s files with their npm dependencies installed; ``what`` says
    which test does not run when node or npm is missing."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        reason = f"{what} NOT RUN: no node/npm on PATH (install Node.js >= 20 with npm)"
        warnings.warn(reason, stacklevel=2)
        pytest.skip(reason)
    dest = ROOT / "build" / name
    dest.mkdir(parents=True, exist_ok=True)
    # pytest-xdist workers may ask for the same tree at once: one installs, the others wait for it.
    with open(ROOT / "build" / f"{name}.lock", "w") as guard:
        fcntl.flock(guard, fcntl.LOCK_EX)
        return _install(source, dest, npm)


def _install(source: Path, dest: Path, npm: str) -> Path:
    lock = dest / "package-lock.json"
    stale = (not (dest / "node_modules").is_dir() or not lock.exists()
             or lock.read_bytes() != (source / "package-lock.json").read_bytes())
    for path in source.iterdir():
        if path.is_file():
            shutil.copyfile(path, dest / path.name)
    if stale:
        proc = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--loglevel=error"], cwd=dest,
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, f"npm ci in {dest} failed:\n{proc.stdout}\n{proc.stderr}"
    return dest
