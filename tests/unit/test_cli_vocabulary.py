"""One CLI vocabulary: an option name shared by subcommands means the same in each. Every subcommand's parser is
built (``build_parser()``, nested subcommands included) and every option two of them share is compared: whether
it takes a value, the value's form (metavar), its type where both say one, and the unit its help names."""

from __future__ import annotations

import argparse
import importlib
import re
import typing
from collections import defaultdict

from aioadept.cli import SUBCOMMANDS

UNITS = ("mm/s", "mm", "ms", "seconds", "s", "deg", "%", "Hz")
UNIT_RE = re.compile(r"(?<![\w/'])(" + "|".join(re.escape(u) for u in UNITS) + r")(?![\w/])")
SAME_UNIT = {"seconds": "s"}


def parsers() -> dict[str, argparse.ArgumentParser]:
    out = {}
    for name, (module, _help) in SUBCOMMANDS.items():
        parser = importlib.import_module(module).build_parser()
        out[name] = parser
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                out.update({f"{name} {sub}": p for sub, p in action.choices.items()})
    return out


def value_type(action: argparse.Action) -> str | None:
    """The type of the value an option gives: a builtin's name, a parser function's result type (its return
    annotation; one value or a sequence of them counts the same), ``str`` for a choice; None when not said."""
    kind = action.type
    if kind is None:
        return "str" if action.choices is not None else None
    if isinstance(kind, type):
        return "str" if kind.__name__ == "Path" else kind.__name__
    result = typing.get_type_hints(kind).get("return")
    args = typing.get_args(result)
    result = args[0] if args else result
    return getattr(result, "__name__", None)


def meaning(action: argparse.Action) -> dict[str, object]:
    metavar = action.metavar if isinstance(action.metavar, str) else None
    kind = value_type(action)
    units = set()
    if kind != "str":  # a number's unit; a name's help may mention units of other things
        units = {SAME_UNIT.get(u, u) for u in UNIT_RE.findall((action.help or "").replace("%%", "%"))}
    return {"takes a value": action.nargs != 0,
            "form": metavar.split("[,")[0] if metavar else None,  # MM[,MM...]: a list of the same MM
            "type": kind, "unit": units}


def mismatches(uses: dict[str, argparse.Action]) -> list[str]:
    said = {cmd: meaning(a) for cmd, a in uses.items()}
    out = []
    for key in ("takes a value", "form", "type", "unit"):
        values = {cmd: m[key] for cmd, m in said.items() if m[key] not in (None, set())}
        if key == "form" and any(m["takes a value"] for m in said.values()):
            values = {cmd: m[key] for cmd, m in said.items() if m["takes a value"]}
        if len({repr(v) for v in values.values()}) > 1:
            out.append(f"{key}: {values}")
    return out


def test_a_shared_option_means_the_same_in_every_subcommand():
    # the comparison sees a flag against a value and a unit against another, and nothing else
    flag, value = argparse.ArgumentParser(), argparse.ArgumentParser()
    a = flag.add_argument("--vplus", action="store_true")
    b = value.add_argument("--vplus", nargs="+", metavar="FILE")
    assert mismatches({"x": a, "y": b})
    c = flag.add_argument("--timeout", type=float, help="seconds")
    d = value.add_argument("--timeout", type=float, help="in ms")
    assert mismatches({"x": c, "y": d}) == ["unit: {'x': {'s'}, 'y': {'ms'}}"]
    e = value.add_argument("--wait", type=float, metavar="S", help="wait, s")
    f = flag.add_argument("--wait", type=float, metavar="S", help="how long, seconds")
    assert mismatches({"x": e, "y": f}) == []

    options: dict[str, dict[str, argparse.Action]] = defaultdict(dict)
    for cmd, parser in parsers().items():
        for action in parser._actions:
            for opt in action.option_strings:
                if opt not in ("-h", "--help"):
                    options[opt][cmd] = action
    shared = {opt: uses for opt, uses in options.items() if len(uses) > 1}
    assert {"--robot", "--config", "--out", "--delta-z", "--stop-port"} <= set(shared)
    assert "send" in shared["--robot"], "aioadept send takes --robot HOST[:PORT] as every client does"
    found = {opt: bad for opt, uses in sorted(shared.items()) if (bad := mismatches(uses))}
    assert found == {}, f"options that mean different things in different subcommands: {found}"
