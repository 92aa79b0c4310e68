"""Every subcommand's ``--help`` reads as plain text: no reST markup, and each option's default said once.

``aioadept sim --help`` runs as a real ``python -m aioadept`` process, the others in this process
(tests/integration/cliinproc.py): the same exit status and text."""

from __future__ import annotations

import re

import pytest

from aioadept.cli import SUBCOMMANDS

from cliinproc import run_inproc, run_real


def _help(name: str) -> str:
    proc = (run_real if name == "sim" else run_inproc)(name, "--help")
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def _option_entries(text: str) -> list[str]:
    """Each option's help, its continuation lines joined."""
    entries: list[str] = []
    for line in text.splitlines():
        if re.match(r"^  -", line):
            entries.append(line)
        elif entries and line.startswith("   "):
            entries[-1] += " " + line.strip()
        elif not line.strip() or not line.startswith(" "):
            entries.append("")  # a section heading or blank line ends the entry
    return [e for e in entries if e]


@pytest.mark.timeout(120)
@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_help_has_no_markup_and_says_each_default_once(name):
    text = _help(name)
    assert "`" not in text, text
    for entry in _option_entries(text):
        assert len(re.findall(r"\(default", entry)) <= 1, entry
