"""V+ line coverage with coverage.py: which lines of ``.V2`` files ran in the emulator, reported beside the Python
files by ``coverage report``/``html``/``xml``/``lcov``/``json`` and ``pytest --cov``.

Configured as a coverage.py plugin (docs/vplus.md, "Line coverage of V+ code")::

    [tool.coverage.run]
    plugins = ["aioadept.vplus.coverage_plugin"]

How it works: :func:`coverage_init` registers :class:`VPlusPlugin` and attaches a :class:`LineTracer` (the
emulator's tracer API, :mod:`aioadept.vplus.trace`) to every emulator runtime made after it, in this process and,
with coverage's ``patch = ["subprocess"]``, in every ``aioadept sim --vplus`` it starts. The tracer asks for the
line hook at every statement of every program not seen yet (``Runtime.trace_lines``); the first time a line runs
it drops the line from the set (from then on the hook costs a set look-up) and runs a one-line *beacon*: code
compiled with the ``.V2`` file's path and that line number. coverage.py's own tracer records the beacon as a line
of that file, and saves it with the rest of its data (contexts, parallel files, combine), so nothing here writes
coverage data. The plugin's file tracer claims ``.V2``/``.pg`` files; its file reporter gives their executable
lines (the statements the compiler puts a line hook before: :func:`executable_lines`) and their source.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import Any

import coverage

from aioadept.vplus import linehits
from aioadept.vplus.linehits import LineRecorder, _hooked, executable_lines  # noqa: F401  (the reporter's rule)
from aioadept.vplus.loader import strip_comment

SUFFIXES = (".v2", ".pg")
"""The files the plugin claims (case-insensitive)."""


def is_vplus(filename: str) -> bool:
    return filename.lower().endswith(SUFFIXES)


# -- recording: the emulator's tracer ----------------------------------------------------------------------------

class LineTracer(LineRecorder):
    """The emulator's tracer for one runtime: the first run of each line of a file that exists is reported to
    coverage.py by a beacon (:func:`beacon`)."""

    seen: set[tuple[str, int]] = set()
    """(path, line) already reported in this process: a later runtime does not hook them again."""

    def __init__(self, rt: Any, hits: set[tuple[str, int]] | None = None) -> None:
        super().__init__(rt, self.seen if hits is None else hits)

    def record(self, path: str, line: int) -> None:
        beacon(path, line)


def beacon(path: str, line: int) -> None:
    """Run one line of code that Python attributes to ``path`` at ``line``: coverage.py's tracer records it."""
    exec(compile("\n" * (line - 1) + "_ = 0", path, "exec"), {})


def attach(rt: Any) -> None:
    """Trace ``rt`` (a :class:`aioadept.vplus.runtime.Runtime` with no task running) for line coverage; not one
    whose programs come from no file (``Emulator.from_source``): there is no file to report."""
    linehits.attach(rt, recorder=LineTracer)


def install() -> None:
    """Attach :func:`attach` to every runtime made from now on in this process (once)."""
    from aioadept.vplus.runtime import Runtime

    init = Runtime.__init__
    if getattr(init, "vplus_coverage", False):
        return

    @functools.wraps(init)
    def traced_init(self: Runtime, *args: Any, **kwargs: Any) -> None:
        init(self, *args, **kwargs)
        attach(self)

    traced_init.vplus_coverage = True       # type: ignore[attr-defined]
    Runtime.__init__ = traced_init          # type: ignore[method-assign]


# -- the coverage.py plugin --------------------------------------------------------------------------------------

class VPlusPlugin(coverage.CoveragePlugin):
    """Claims ``.V2``/``.pg`` files: their lines as the beacons record them, their report by :class:`VPlusReporter`."""

    def file_tracer(self, filename: str) -> coverage.FileTracer | None:
        return VPlusFileTracer(filename) if is_vplus(filename) else None

    def file_reporter(self, filename: str) -> coverage.FileReporter:
        return VPlusReporter(filename)

    def find_executable_files(self, src_dir: str):
        """The V+ files under a measured source folder: reported (as not run) even when nothing ran them."""
        for root, _, files in os.walk(src_dir):
            for f in files:
                if is_vplus(f):
                    yield os.path.join(root, f)


class VPlusFileTracer(coverage.FileTracer):
    def __init__(self, filename: str) -> None:
        self.filename = filename

    def source_filename(self) -> str:
        return self.filename


class VPlusReporter(coverage.FileReporter):
    """A ``.V2`` file's report: its executable lines and its source (read as the loader reads it, Latin-1)."""

    @functools.cached_property
    def text(self) -> str:
        return Path(self.filename).read_bytes().decode("latin-1")

    def source(self) -> str:
        return self.text

    def lines(self) -> set[int]:
        return executable_lines(self.text, Path(self.filename).name)

    def source_token_lines(self):
        """The source for HTML: each line plain text (a comment from its ``;``), no V+ highlighting."""
        for line in self.text.replace("\r\n", "\n").replace("\r", "\n").split("\n"):
            code = strip_comment(line)
            yield [("txt", code)] + ([("com", line[len(code):])] if len(code) < len(line) else [])


def coverage_init(reg: Any, options: dict) -> None:
    """coverage.py's entry point (``plugins = ["aioadept.vplus.coverage_plugin"]``)."""
    reg.add_file_tracer(VPlusPlugin())
    install()
