"""The OPC UA server's dependencies ship: the OPC Foundation's DI, IA and Robotics NodeSet2 files are package data
with their licence header, and ``pip install -r requirements.lock`` gives every distribution the ``[opcua]`` extra
needs (asyncua and its whole tree, pinned)."""

from __future__ import annotations

import fnmatch
import importlib.metadata
import tomllib
from importlib import resources
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[3]
MODELS = {"Opc.Ua.Di.NodeSet2.xml": "http://opcfoundation.org/UA/DI/",
          "Opc.Ua.IA.NodeSet2.xml": "http://opcfoundation.org/UA/IA/",
          "Opc.Ua.Robotics.NodeSet2.xml": "http://opcfoundation.org/UA/Robotics/"}


@pytest.mark.parametrize("name", sorted(MODELS))
def test_each_nodeset_is_package_data_with_its_licence_and_model(name: str) -> None:
    text = (resources.files("aioadept.opcua") / "nodesets" / name).read_text(encoding="utf-8")
    head = text[:2000]
    assert "Copyright (c) 2005-2024 The OPC Foundation, Inc." in head
    assert "OPC Foundation MIT License 1.00" in head and "http://opcfoundation.org/License/MIT/1.00/" in head
    assert f'<Model ModelUri="{MODELS[name]}"' in text


def test_pyprojects_package_data_ships_the_nodesets() -> None:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    globs = cfg["tool"]["setuptools"]["package-data"]["aioadept"]
    for name in MODELS:
        assert any(fnmatch.fnmatch(f"opcua/nodesets/{name}", g) for g in globs), (name, globs)


def _lock() -> dict[str, str]:
    pins = {}
    for line in (ROOT / "requirements.lock").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            req = Requirement(line)
            pins[canonicalize_name(req.name)] = str(req.specifier)
    return pins


def test_the_lock_pins_the_opcua_extra_and_everything_it_needs() -> None:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    extra = [Requirement(r) for r in cfg["project"]["optional-dependencies"]["opcua"]]
    assert [r.name for r in extra] == ["asyncua"]
    pins = _lock()
    todo, seen = list(extra), set()
    while todo:
        req = todo.pop()
        name = canonicalize_name(req.name)
        if name in seen or (req.marker is not None and not req.marker.evaluate({"extra": ""})):
            continue
        seen.add(name)
        assert name in pins, f"requirements.lock does not pin {name} (needed by the [opcua] extra)"
        dist = importlib.metadata.distribution(name)
        assert pins[name] == f"=={dist.version}", (name, pins[name], dist.version)
        assert req.specifier.contains(dist.version), (name, dist.version, str(req.specifier))
        todo += [Requirement(r) for r in dist.requires or ()]
    assert "asyncua" in seen and "cryptography" in seen
