"""The import rules of src/aioadept, read from the source (ast; nothing is imported or run).

- No cycles between modules: a cycle means two modules that cannot be understood (or imported) one at a time.
  Imports under ``if TYPE_CHECKING:`` count too: they are dependencies of the reader's understanding.
- The sans-IO protocol core (``aioadept.protocol``) imports neither asyncio, socket nor time, nor anything of
  aioadept outside itself but ``aioadept.geometry`` and ``aioadept.errors`` (two leaves: they import nothing of
  aioadept); the client's registry (``aioadept.client.registry``) no asyncio, socket or time either.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"
PKG = SRC / "aioadept"

# Cycles known today, each to be removed by the issue item named. Nothing else may be added here.
KNOWN_CYCLES: list[frozenset[str]] = [
    # the recording package and its viewer, to be split
    frozenset({"aioadept.record", "aioadept.record.viewer"}),
]

# Dependencies that point the wrong way: (importer prefix, imported prefix). The vision side must not need the
# simulator, the bus must not know its users.
FORBIDDEN = [("aioadept.vision", "aioadept.sim"), ("aioadept.bus", "aioadept.vision"),
             ("aioadept.protocol", "aioadept.client"), ("aioadept.client", "aioadept.sim")]
KNOWN_WRONG_WAY: set[tuple[str, str]] = set()


def module_name(path: Path) -> str:
    parts = path.relative_to(SRC).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in PKG.rglob("*.py")}


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    """The aioadept modules ``name`` imports (``from pkg import mod`` counts as the module when it is one), and
    the names of stdlib top-level modules it imports (prefixed ``std:``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    is_pkg = path.name == "__init__.py"
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                out.add(alias.name if alias.name.startswith("aioadept") else "std:" + alias.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_pkg else name.split(".")[:-1]
                base = base[:len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if not mod.startswith("aioadept"):
                out.add("std:" + mod.split(".")[0])
                continue
            for alias in node.names:
                sub = f"{mod}.{alias.name}"
                out.add(sub if sub in known else mod)
    # The top-level package is every module's parent: an edge to it says nothing about design.
    return {m for m in out if m != "aioadept" and m != name}


@functools.cache
def graph() -> dict[str, set[str]]:
    """The import graph of the package, read once per test session (the tests only read it)."""
    mods = modules()
    known = set(mods)
    g = {}
    for name, path in mods.items():
        deps = imports_of(name, path, known)
        g[name] = {d for d in deps if d in known}
    return g


def cycles(g: dict[str, set[str]]) -> list[frozenset[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[frozenset[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(g.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(frozenset(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def test_the_graph_is_read_from_the_source():
    g = graph()
    assert "aioadept.client.robot" in g and "aioadept.client.registry" in g["aioadept.client.robot"]
    assert "aioadept.protocol.messages" in g["aioadept.protocol.reader"]


def test_no_import_cycles_but_the_known_ones():
    found = cycles(graph())
    new = [sorted(c) for c in found if c not in KNOWN_CYCLES]
    assert new == [], f"import cycles: {new}"
    gone = [sorted(c) for c in KNOWN_CYCLES if c not in found]
    assert gone == [], f"these known cycles are gone: remove them from KNOWN_CYCLES: {gone}"


def test_dependencies_point_one_way():
    g = graph()
    wrong = {(m, d) for m, deps in g.items() for d in deps for a, b in FORBIDDEN
             if (m == a or m.startswith(a + ".")) and (d == b or d.startswith(b + "."))}
    assert wrong - KNOWN_WRONG_WAY == set()
    gone = KNOWN_WRONG_WAY - wrong
    assert gone == set(), f"remove from KNOWN_WRONG_WAY: {gone}"


def test_protocol_core_is_sans_io():
    mods = modules()
    known = set(mods)
    for name, path in mods.items():
        rules = []
        if name == "aioadept.protocol" or name.startswith("aioadept.protocol."):
            rules = ["protocol"]
        elif name == "aioadept.client.registry":
            rules = ["registry"]
        if not rules:
            continue
        deps = imports_of(name, path, known)
        assert not deps & {"std:asyncio", "std:socket", "std:time", "std:selectors"}, (name, sorted(deps))
        if rules == ["protocol"]:
            outside = {d for d in deps if not d.startswith("std:") and not d.startswith("aioadept.protocol")
                       and d not in LEAVES}
            assert outside == set(), f"{name} imports {sorted(outside)} from outside the protocol core"


LEAVES = ("aioadept.geometry", "aioadept.errors")
"""Modules every layer may import, the sans-IO core included: they import nothing of aioadept."""


def test_the_leaves_import_nothing_of_aioadept():
    g = graph()
    assert {leaf: sorted(g[leaf]) for leaf in LEAVES} == {leaf: [] for leaf in LEAVES}


# The command line is the outermost layer. Only it imports ``aioadept.cli``, besides the ``python -m``
# entry points (``__main__`` modules), which are command lines themselves; no library leans on it.
CLI_IMPORTERS_ALLOWED = {"aioadept.__main__", "aioadept.sim.__main__", "aioadept.vision.__main__"}


def test_only_the_command_line_imports_the_command_line():
    g = graph()
    leaning = {m for m, deps in g.items() if any(d == "aioadept.cli" or d.startswith("aioadept.cli.") for d in deps)
               and not (m == "aioadept.cli" or m.startswith("aioadept.cli."))}
    assert leaning <= CLI_IMPORTERS_ALLOWED, f"modules outside cli/ that import it: {sorted(leaning)}"
    for shim in ("aioadept.client_cli", "aioadept.apps.focus_cli", "aioadept.apps.cli_common",
                 "aioadept.analysis.__main__"):
        assert shim not in g, f"{shim} is back"
