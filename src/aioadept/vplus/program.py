"""What a loaded program is: its parameters, its parsed steps (statement nodes by line) and its problems.

Shared by :mod:`~aioadept.vplus.loader`, which makes programs, and :mod:`~aioadept.vplus.compiler`, which reads
them; nothing here parses or compiles.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True, slots=True)
class LoadProblem:
    """A line that did not load: ``file:line: message (word)``; ``column`` is where the word starts."""

    file: str
    line: int
    message: str
    word: str
    program: str | None
    column: int = 0          # 1-based, at the offending token (0: not known)

    def __str__(self) -> str:
        where = f" in {self.program}" if self.program else ""
        return f"{self.file}:{self.line}: {self.message}{where} [{self.word}]"


@dataclass(slots=True)
class Param:
    name: str          # normalised, with $/# prefix
    is_array: bool


@dataclass(slots=True)
class Program:
    """One ``.PROGRAM``: its parameters and parsed steps ``(line number, statement)``."""

    name: str
    params: list[Param]
    file: str
    line: int
    steps: list[tuple[int, Any]] = field(default_factory=list)
    source: dict[int, str] = field(default_factory=dict)
    indent: dict[int, int] = field(default_factory=dict)      # characters before each source line's text
    problems: list[LoadProblem] = field(default_factory=list)

    @property
    def executable(self) -> bool:
        return not self.problems
