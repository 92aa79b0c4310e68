"""The one exception tree: every public exception of the package is an ``AdeptError`` defined in
:mod:`aioadept.errors`, keeps the builtin base callers catch it by, and is drawn in that module's docstring."""

from __future__ import annotations

import builtins
import importlib
import inspect
import pkgutil
import re

import aioadept
import aioadept.errors as errors
from aioadept.errors import AdeptError

OUTSIDE_THE_TREE = {
    # Stands in for a bug of the server (``Faults(raise_at=...)``): the server must treat it as it treats any bug,
    # so it must not be one of the errors it raises on purpose.
    "aioadept.sim.server.InjectedFault",
}

DEFINED_BESIDE_THEIR_TABLE = (
    # The V+ emulator's errors: a V+ program's error takes its text from V+'s table of error codes, which is the
    # emulator's (aioadept.errors imports nothing of aioadept). They are AdeptErrors, named in aioadept.errors'
    # docstring.
    "aioadept.vplus.",
)


def exempt(name: str) -> bool:
    return name in OUTSIDE_THE_TREE


def public_exceptions() -> dict[str, type[Exception]]:
    """Every public ``Exception`` subclass defined in a module of the package, by ``module.Name``. Control-flow
    signals (``BaseException`` but not ``Exception``) are not errors and are left out."""
    found: dict[str, type[Exception]] = {}
    for info in pkgutil.walk_packages(aioadept.__path__, "aioadept."):
        if info.name.endswith("__main__"):
            continue  # running it is its import
        try:
            module = importlib.import_module(info.name)
        except ModuleNotFoundError as exc:
            if (exc.name or "").startswith("aioadept"):
                raise
            continue  # an optional extra is not installed
        if any(part.startswith("_") for part in info.name.split(".")):
            continue
        for name, obj in vars(module).items():
            if (inspect.isclass(obj) and issubclass(obj, Exception) and obj.__module__ == module.__name__
                    and not name.startswith("_")):
                found[f"{module.__name__}.{name}"] = obj
    return found


def test_every_public_exception_is_an_adept_error_defined_in_errors():
    found = public_exceptions()
    assert "aioadept.errors.CommandError" in found and "aioadept.sim.server.InjectedFault" in found
    outside = sorted(k for k, cls in found.items() if not issubclass(cls, AdeptError) and not exempt(k))
    assert outside == [], f"public exceptions outside AdeptError: {outside}"
    elsewhere = sorted(k for k in found if not k.startswith(("aioadept.errors.", *DEFINED_BESIDE_THEIR_TABLE))
                       and not exempt(k))
    assert elsewhere == [], f"exceptions defined outside aioadept.errors: {elsewhere}"
    assert OUTSIDE_THE_TREE <= set(found), "listed but gone: remove it from OUTSIDE_THE_TREE"


def test_the_emulators_errors_are_named_in_the_trees_docstring():
    found = public_exceptions()
    emulator = sorted(k.rsplit(".", 1)[1] for k in found if k.startswith(DEFINED_BESIDE_THEIR_TABLE))
    assert "VPlusError" in emulator and "LoadError" in emulator, emulator
    missing = [name for name in emulator if f"``{name}``" not in (errors.__doc__ or "")]
    assert missing == [], f"emulator errors not named in aioadept.errors' docstring: {missing}"


def test_the_builtin_bases_callers_catch_by_are_kept():
    kept = {"ConfigError": ValueError, "BadRequest": ValueError, "BadLocateRequest": ValueError,
            "CalibrationError": ValueError, "MalformedRequest": ValueError, "BusEncodeError": ValueError,
            "GraphError": ValueError, "ViewerUnavailable": RuntimeError, "RunSaveError": OSError, "AnalysisSaveError": OSError,
            "AckTimeout": TimeoutError, "RequestTimeout": TimeoutError}
    for name, base in kept.items():
        assert issubclass(getattr(errors, name), AdeptError) and issubclass(getattr(errors, name), base), name


def drawing() -> dict[str, tuple[str, str]]:
    """The tree drawn in :mod:`aioadept.errors`' docstring: name -> (parent, builtin base shown in brackets)."""
    doc = errors.__doc__ or ""
    block = doc[doc.index("    AdeptError"):].split("\n\n")[0]
    drawn: dict[str, tuple[str, str]] = {}
    stack: list[tuple[int, str]] = []
    for line in block.splitlines():
        m = re.match(r"^([ │├└─]*)([A-Z]\w+)(?: \((\w+)\))?", line)
        assert m, line
        column = len(m.group(1))
        while stack and stack[-1][0] >= column:
            stack.pop()
        drawn[m.group(2)] = (stack[-1][1] if stack else "", m.group(3) or "")
        stack.append((column, m.group(2)))
    return drawn


def test_the_docstring_draws_every_error_under_its_parent():
    drawn = drawing()
    classes = {n for n in errors.__all__ if inspect.isclass(getattr(errors, n))}
    assert set(drawn) == classes, f"drawn but not defined: {set(drawn) - classes}; not drawn: {classes - set(drawn)}"
    for name, (parent, builtin) in drawn.items():
        cls = getattr(errors, name)
        assert cls.__bases__[0] is (getattr(errors, parent) if parent else Exception), (name, parent)
        if builtin:
            assert issubclass(cls, getattr(builtins, builtin)), (name, builtin)
