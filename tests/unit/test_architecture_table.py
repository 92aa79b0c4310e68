"""docs/architecture.md's table of the tree names every package and top-level module of ``src/aioadept`` (and
nothing that is gone), and says which ``vplus`` is which: the controller's programs or the emulator."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "src" / "aioadept"


def _tree() -> set[str]:
    """``src/aioadept/NAME/`` for each package, ``src/aioadept/NAME.py`` for each module (dunder files aside)."""
    out = set()
    for p in PKG.iterdir():
        if p.is_dir() and (p / "__init__.py").is_file():
            out.add(f"src/aioadept/{p.name}/")
        elif p.suffix == ".py" and not p.name.startswith("__"):
            out.add(f"src/aioadept/{p.name}")
    return out


def _table(text: str) -> set[str]:
    """The ``src/aioadept/...`` paths in the first column of the table's rows."""
    out = set()
    for line in text.splitlines():
        if line.startswith("| `"):
            first = line.split("|")[1]
            out.update(p for p in re.findall(r"`([^`]+)`", first) if p.startswith("src/aioadept/"))
    return out


def test_the_package_table_matches_the_tree() -> None:
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    listed, tree = _table(text), _tree()
    assert sorted(tree - listed) == [], "in src/aioadept but not in docs/architecture.md's table"
    assert sorted(listed - tree) == [], "in docs/architecture.md's table but not in src/aioadept"
    assert "`vplus/` holds the controller's programs (V+ source); `aioadept.vplus` is the emulator" in text

