"""Griffe extension for the API reference (mkdocs.yml): the docstrings are written with reST roles and literal
blocks (``:class:`RobotClient```, ``over asyncio::``), which Markdown would show as they are. This turns a role into
a cross-reference to the named object (plain inline code when the name is not documented) and ``::`` into ``:``;
the indented block after it is already a Markdown code block. The docstrings themselves are not changed.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(mod|class|func|meth|attr|exc|data|obj|const):`(~?)([^`<]+?)`")
LITERAL = re.compile(r"(\S)::[ \t]*$", re.M)


def _role(m: re.Match[str]) -> str:
    tilde, target = m.group(2), m.group(3).strip()
    shown = target.rsplit(".", 1)[-1] if tilde else target
    if target.startswith("aioadept."):
        return f"[`{shown}`][{target}]"      # mkdocs-autorefs resolves it; an unknown target stays plain text
    return f"`{shown}`"


class RstRoles(griffe.Extension):
    def on_object(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            text = ROLE.sub(_role, obj.docstring.value)
            obj.docstring.value = LITERAL.sub(r"\1:", text)
