"""One import path per name: a name is imported from the module that defines it, or from a package's
``__init__`` (the package's public face). No other module re-exports a name defined elsewhere, and no old name
stays as an alias of a new one. Read from the source (ast); nothing is imported but :mod:`aioadept` itself."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import aioadept
import aioadept.commands

SRC = Path(__file__).resolve().parents[2] / "src"
PKG = SRC / "aioadept"

NOT_YET = {
    # The robot models' modules, being reworked, each to lose these names.
    "aioadept.robots.viper_s850": {"DEFAULT_JUMP_LIMIT", "ConfigRequest", "Configuration", "JointLimits", "JumpLimit",
                                   "_matches", "_nearest_equivalent", "_wrap_pi", "ELBOW_FREE_DEG",
                                   "SHOULDER_FREE_MM", "WRIST_FREE_DEG", "WRIST_SINGULAR_SIN", "MODEL"},
    "aioadept.robots.viper_s850_urdf": {"BASE_LINK", "FLANGE_LINK", "UrdfJoint", "quaternion_xyzw"},
}

NOT_YET_PACKAGES = (
    # The V+ emulator, being reworked (its runtime's generated code also reads names through the module).
    "aioadept.vplus.",
)


def re_exports(path: Path) -> set[str]:
    """The names ``path`` offers that are defined elsewhere: imported from aioadept and listed in ``__all__``,
    imported and never used, star-imported, or bound to a public alias (``Old = New``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    imported: set[str] = set()
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("aioadept")):
            for alias in node.names:
                if alias.name == "*":
                    out.add(f"* from {node.module}")
                else:
                    imported.add(alias.asname or alias.name)
    used = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load)}
    used |= {n.value.id for n in ast.walk(tree) if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name)}
    used |= {name for text in quoted_annotations(tree) for name in
             (n.id for n in ast.walk(ast.parse(text, mode="eval")) if isinstance(n, ast.Name))}
    local = {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))}
    listed: set[str] = set()
    for node in tree.body:
        if not isinstance(node, ast.Assign) or len(node.targets) != 1 or not isinstance(node.targets[0], ast.Name):
            continue
        target = node.targets[0].id
        if target == "__all__":
            listed = {e.value for e in node.value.elts if isinstance(e, ast.Constant)}  # type: ignore[attr-defined]
        elif (isinstance(node.value, ast.Name) and node.value.id in imported | local
              and not target.startswith("_")):
            out.add(target)
    out |= listed & imported
    out |= {name for name in imported if name not in used and name not in listed}
    return out


def quoted_annotations(tree: ast.AST) -> list[str]:
    """Annotations written as strings (``x: "CellConfig"``): a name they mention is used."""
    found = []
    for node in ast.walk(tree):
        notes = []
        if isinstance(node, ast.arg):
            notes = [node.annotation]
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            notes = [node.returns]
        elif isinstance(node, ast.AnnAssign):
            notes = [node.annotation]
        found += [n.value for n in notes if isinstance(n, ast.Constant) and isinstance(n.value, str)]
    return found


def module_name(path: Path) -> str:
    return ".".join(path.relative_to(SRC).with_suffix("").parts)


def test_no_module_re_exports_a_name_defined_elsewhere(tmp_path):
    # the rule sees each kind of re-export, and only those
    cases = {
        "from aioadept.geometry import Pose\n__all__ = ['Pose']\n": {"Pose"},
        "from aioadept.geometry import Pose  # noqa: F401\n": {"Pose"},
        "from aioadept.geometry import *  # noqa: F403\n": {"* from aioadept.geometry"},
        "class New: ...\nOld = New\n": {"Old"},
        "from aioadept.geometry import Pose\ndef f(p: Pose) -> Pose: return p\n": set(),
        "from aioadept.geometry import Pose\ndef f(p: 'Pose') -> None: ...\n": set(),
        "from aioadept import geometry\nx = geometry.Pose\n": set(),
        "from aioadept.geometry import Pose as _P\n_FAST = _P\n": set(),
    }
    for source, want in cases.items():
        path = tmp_path / "m.py"
        path.write_text(source)
        assert re_exports(path) == want, source

    found = {}
    for path in sorted(PKG.rglob("*.py")):
        if path.name == "__init__.py" or module_name(path).startswith(NOT_YET_PACKAGES):
            continue
        names = re_exports(path) - NOT_YET.get(module_name(path), set())
        if names:
            found[module_name(path)] = sorted(names)
    assert found == {}, f"re-exported names (import them from where they are defined): {found}"


def test_the_client_and_every_command_import_from_aioadept():
    from aioadept import Appro, MoveToS, RobotClient  # noqa: F401

    commands = {n for n, o in vars(aioadept.commands).items() if inspect.isclass(o) and not n.startswith("_")
                and issubclass(o, aioadept.commands.Command) and o.__module__ == "aioadept.commands"}
    assert "MoveToS" in commands and "Appro" in commands
    assert sorted(commands - set(aioadept.__all__)) == []
    assert all(getattr(aioadept, n) is getattr(aioadept.commands, n) for n in commands)
