"""The bus's shape (no sockets): the pending registry's rules, the bus knowing none of its users, one socket layer,
and the package exporting its public names."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import aioadept.bus
from aioadept.bus.pairing import PendingRegistry
from aioadept.errors import ClientStateError

BUS = Path(aioadept.bus.__file__).parent
SOURCES = sorted(p for p in BUS.glob("*.py") if not p.name.endswith("_pb2.py"))


def imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
    return out


def test_pending_registry_adds_once_and_removes_on_every_path():
    reg: PendingRegistry[str, int] = PendingRegistry("request")
    assert reg.add("a", 1) == 1 and reg.add("b", 2) == 2
    with pytest.raises(ClientStateError, match="'a' is already outstanding"):
        reg.add("a", 3)
    assert reg.get("a") == 1 and "a" in reg and len(reg) == 2 and reg.keys() == ("a", "b")
    assert reg.pop("a") == 1 and reg.pop("a") is None  # idempotent: every exit path may call it
    reg.add("a", 4)  # the id is free again once settled
    assert list(reg) == ["b", "a"] and reg.drain() == [2, 4] and len(reg) == 0 and reg.keys() == ()


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_the_bus_knows_none_of_its_users(path):
    users = ("aioadept.vision", "aioadept.apps", "aioadept.sim", "aioadept.client", "aioadept.record",
             "aioadept.runs.capture", "aioadept.analysis", "aioadept.cli")
    bad = sorted(m for m in imported_modules(path) if m.startswith(users))
    assert not bad, f"{path.name} imports {bad}"
    assert "aioadept.errors.VisionError" not in imported_modules(path)


def test_one_socket_layer_creates_and_binds_every_socket():
    # Only sockets.py creates sockets and binds/connects them (security.py sets CURVE options on them).
    for path in SOURCES:
        if path.name in ("sockets.py", "security.py"):
            continue
        text = path.read_text()
        for needle in ("zmq.Socket(", ".socket(zmq.", ".bind(", ".connect(", "setsockopt(zmq.LINGER"):
            assert needle not in text, f"{path.name} builds its own socket plumbing ({needle})"


def test_no_bus_module_over_500_lines_without_saying_why():
    for path in SOURCES:
        lines = path.read_text().splitlines()
        if len(lines) > 500:
            assert "over 500 lines" in "\n".join(lines[:30]), f"{path.name}: {len(lines)} lines, no reason given"


def test_the_package_exports_its_public_names():
    for name in aioadept.bus.__all__:
        assert getattr(aioadept.bus, name) is not None
