"""Griffe extension for the API reference (mkdocs.yml): the docstrings are written with reST roles and literal
blocks (``:class:`RobotClient```, ``over asyncio::``), which Markdown would show as they are. This turns a role into
a cross-reference to the named object (plain inline code when it has no API page) and ``::`` into ``:``;
the indented block after it is already a Markdown code block. The docstrings themselves are not changed.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(mod|class|func|meth|attr|exc|data|obj|const):`(~?)([^`<]+?)`")
LITERAL = re.compile(r"(\S)::[ \t]*$", re.M)


# The packages that have an API page (docs/api/): only names inside them, and public, are linked. Any other name
# would be a link without a target, which the strict build rejects.
DOCUMENTED = ("client", "commands", "errors", "protocol", "sim", "bus", "vision", "apps", "testing")


def _linkable(target: str) -> bool:
    parts = target.split(".")
    return (len(parts) >= 2 and parts[0] == "aioadept" and parts[1] in DOCUMENTED
            and not any(p.startswith("_") for p in parts))


def _role(m: re.Match[str]) -> str:
    tilde, target = m.group(2), m.group(3).strip()
    shown = target.rsplit(".", 1)[-1] if tilde else target
    if _linkable(target):
        return f"[`{shown}`][{target}]"      # resolved by mkdocs-autorefs
    return f"`{shown}`"


class RstRoles(griffe.Extension):
    def on_object(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            text = ROLE.sub(_role, obj.docstring.value)
            obj.docstring.value = LITERAL.sub(r"\1:", text)
