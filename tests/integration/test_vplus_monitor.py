"""``aioadept vplus monitor`` on a pseudo-terminal (a real process, line editing on): LOAD, EXECUTE, BPT, STATUS,
LISTR, PROCEED, WHERE, ABORT, an unknown command, and the end of input."""

from __future__ import annotations

import os
import pty
import re
import select
import subprocess
import sys
import time

import pytest

pytestmark = pytest.mark.timeout(60)

COUNTER = """.PROGRAM counter()
; counts, one a trajectory cycle
\tn = 0
\tWHILE TRUE DO
\t    n = n+1
\t    WAIT
\tEND
.END
"""


class Terminal:
    def __init__(self, argv: list[str]) -> None:
        self.master, slave = pty.openpty()
        self.proc = subprocess.Popen(argv, stdin=slave, stdout=slave, stderr=slave, close_fds=True)
        os.close(slave)
        self.seen = ""

    def expect(self, pattern: str, timeout: float = 15.0) -> re.Match:
        """Read until ``pattern`` matches the text after what earlier calls consumed."""
        end = time.monotonic() + timeout
        while True:
            m = re.search(pattern, self.seen)
            if m:
                self.seen = self.seen[m.end():]
                return m
            left = end - time.monotonic()
            if left <= 0:
                raise AssertionError(f"{pattern!r} not seen in {self.seen!r}")
            if select.select([self.master], [], [], left)[0]:
                try:
                    self.seen += os.read(self.master, 4096).decode(errors="replace")
                except OSError:
                    raise AssertionError(f"the monitor ended; {pattern!r} not seen in {self.seen!r}") from None

    def send(self, line: str) -> None:
        os.write(self.master, line.encode() + b"\r")


def test_the_monitor_loads_runs_breaks_proceeds_and_aborts_on_a_terminal(tmp_path):
    src = tmp_path / "count.V2"
    src.write_text(COUNTER)
    term = Terminal([sys.executable, "-m", "aioadept", "vplus", "monitor"])
    try:
        term.expect(r"\. ")
        term.send(f"LOAD {src}")
        term.expect(r"\.PROGRAM counter\(\)")
        term.send("EXECUTE 1 counter")
        term.send("BPT counter 5")
        term.expect(r"\(1\) Break at counter, step 5")
        term.send("STATUS")
        term.expect(r"1\s+stopped\s+counter\s+5")
        term.send("LISTR n")
        n = float(term.expect(r"n = (\d+)").group(1))
        term.send("PROCEED 1")
        term.expect(r"\(1\) Break at counter, step 5")
        term.send("LISTR n")
        assert float(term.expect(r"n = (\d+)").group(1)) == n + 1      # one more turn of the loop
        term.send("WHERE")
        term.expect(r"480\.000\s+0\.000\s+710\.000")
        term.send("ABORT 1")
        term.send("STATUS")
        term.expect(r"1\s+aborted\s+counter")
        term.send("LISTR")
        term.send("FROB 1")
        term.expect(r"\*Unknown command\*\r?\n\. ")                # its reply, then the prompt
        os.write(term.master, b"\x04")                          # end of input: the monitor ends
        assert term.proc.wait(timeout=15) == 0
    finally:
        if term.proc.poll() is None:
            term.proc.kill()
            term.proc.wait()
        os.close(term.master)
