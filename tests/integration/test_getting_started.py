"""docs/getting-started.md as a newcomer types it: every command of its shell blocks, in page
order, in ONE bash shell, as written, so a ``cd`` carries over, a ``&`` job keeps running until ``kill %1`` and
nothing waits for a server's READY line unless the page does.

tests/integration/test_docs_promises.py runs the page's ``aioadept`` lines one by one and waits for each server's
READY before the next line: it cannot see a page that sends to a sim before it listens, which a shell does.

As written, with two things supplied: ``<this repository>`` is this checkout (``git clone`` of it), and the clone's
``.venv`` is this checkout's (its ``bin`` linked, ``make``'s install stamp fresh), so ``make demo`` runs the demo
without installing the pinned packages from PyPI (minutes, and the network). A block marked
``<!-- not-run: reason -->`` is left out, as the page runner does. Exit statuses are the page's (``exit status N``
in a line's comment, else 0) and a ``# prints X`` comment's text is in the output.
"""

from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
from pathlib import Path

import pytest
from test_docs_promises import ROOT, SHELL_LANGS, _blocks, _commands, _port_free, _shown_matches

PAGE = "getting-started.md"
PORTS = (1234, 1235, 5560)
"""What the page's sim takes: its --port, the stop port (port + 1) and the default state stream."""
TIME_CAP_S = 150.0


def page_script(rc_log: Path) -> tuple[str, list[tuple[str, int, list[str]]]]:
    """The page's shell commands as one bash script, each followed by a line that logs its exit status; and per
    command (as printed, its expected status, the output the page shows)."""
    lines = []
    expected = []
    for block in _blocks():
        if block.page != PAGE or block.lang not in SHELL_LANGS or block.not_run is not None:
            continue
        for cmd in _commands(block):
            m = re.search(r"exit status (\d+)", cmd.comment)
            expected.append((cmd.argv, int(m.group(1)) if m else 0, cmd.shown))
            lines.append(cmd.argv.replace("<this repository>", shlex.quote(str(ROOT))))
            lines.append(f"printf '%s\\n' \"$?\" >> {shlex.quote(str(rc_log))}")
            if cmd.argv.startswith("git clone"):  # in the clone now: its .venv is this checkout's, installed
                bin_dir = shlex.quote(str(ROOT / ".venv" / "bin"))
                lines.append(f"mkdir .venv && ln -s {bin_dir} .venv/bin && touch .venv/.installed")
    return "\n".join(lines) + "\n", expected


@pytest.mark.timeout(TIME_CAP_S + 30)
def test_every_shell_command_of_getting_started_runs_as_written(tmp_path):
    busy = [p for p in PORTS if not _port_free(p)]
    if busy:
        pytest.skip(f"the page's sim needs port(s) {busy}, in use on this machine")
    rc_log = tmp_path / "rc.log"
    script, expected = page_script(rc_log)
    assert any(argv.startswith("git clone") for argv, _, _ in expected)
    assert any("make demo" in argv for argv, _, _ in expected) and any(" send " in argv for argv, _, _ in expected)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "MPLBACKEND": "Agg"}
    proc = subprocess.Popen(["bash", "-c", script], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        output, _ = proc.communicate(timeout=TIME_CAP_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        output, _ = proc.communicate()
        raise AssertionError(f"the page's commands took more than {TIME_CAP_S:g} s:\n{output[-3000:]}") from None
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    statuses = [int(s) for s in rc_log.read_text().split()] if rc_log.exists() else []
    assert len(statuses) == len(expected), output[-3000:]
    for (argv, want, shown), got in zip(expected, statuses, strict=True):
        assert got == want, f"{PAGE}: `{argv}` exited {got}, the page says {want}:\n{output[-3000:]}"
        for text in shown:
            assert _shown_matches(text, output, argv), f"{PAGE}: `{argv}`: the page shows {text!r}:\n{output}"
    assert "Traceback" not in output, output
    # What the page says make demo leaves: runs/<time>-focus-s25-dz2/ with summary.json and the figures.
    (run,) = (tmp_path / "aioadept" / "runs").glob("*-focus-s25-dz2")
    assert (run / "summary.json").is_file() and (run / "fig09_sharpness.png").is_file()
