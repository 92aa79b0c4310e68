"""Run an ``aioadept`` command in this process, for the mistakes caught before anything starts or binds (argparse
errors, range checks, cell-file keys, listener refusals): :func:`aioadept.cli.main` with stdout and stderr
captured and SystemExit caught, answered in the shape of ``subprocess.run``'s result so the same assertions read
both. A real ``python -m aioadept`` costs about a second of imports; what only a real process shows (the console
entry, the interpreter's exit status) keeps one real-process case in each test file.

An exception other than SystemExit is printed as the interpreter would (a traceback, exit 1), so a test asserting
"no traceback" fails on it. The logging setup and the signal handlers a command may change are put back, and a
command that leaves a signal handler behind fails the test. A command starts as in a fresh process with respect to
the process-wide Zenoh session (:mod:`aioadept.bus.zenoh`): an earlier test's open session is set aside while it
runs and put back after it.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import signal
import subprocess
import sys
import traceback
from pathlib import Path

from aioadept.cli import main

AIOADEPT = [sys.executable, "-m", "aioadept"]

_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def run_real(*args: str, cwd: Path | None = None, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    """The real console entry (``python -m aioadept``) in a subprocess."""
    return subprocess.run([*AIOADEPT, *args], capture_output=True, text=True, timeout=timeout, cwd=cwd)


_ZENOH_STATE = ("_options", "_session", "_tokens", "_announce")


@contextlib.contextmanager
def _fresh_zenoh_state():
    """The process-wide Zenoh session state as a new process has it, and the earlier state back afterwards."""
    from aioadept.bus import zenoh as zb

    saved = {name: getattr(zb, name) for name in _ZENOH_STATE}
    zb._options, zb._session, zb._tokens, zb._announce = zb.ZenohOptions(), None, [], None
    try:
        yield
    finally:
        opened = zb._session
        for name, value in saved.items():
            setattr(zb, name, value)
        if opened is not None:
            opened.close()


def run_inproc(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``aioadept ARGS`` as :func:`aioadept.cli.main` in this process: exit status, stdout and stderr."""
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    handlers_before = {s: signal.getsignal(s) for s in _SIGNALS}
    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        with _fresh_zenoh_state(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(args))
            except SystemExit as exc:
                if exc.code is None or isinstance(exc.code, int):
                    code = exc.code or 0
                else:  # sys.exit("message"): the interpreter prints it, exit 1
                    print(exc.code, file=sys.stderr)
                    code = 1
            except Exception:  # noqa: BLE001  (the interpreter's answer to an uncaught exception)
                traceback.print_exc()
                code = 1
    finally:
        os.chdir(here)
        root.handlers[:] = handlers
        root.setLevel(level)
        handlers_after = {s: signal.getsignal(s) for s in _SIGNALS}
        for s, h in handlers_before.items():
            signal.signal(s, h)
    assert handlers_after == handlers_before, f"aioadept {' '.join(args)} left signal handlers behind"
    return subprocess.CompletedProcess(["aioadept", *args], code, out.getvalue(), err.getvalue())
