"""V+ line coverage: the coverage.py plugin ``aioadept.vplus.coverage_plugin``, run for real.

One ``coverage run`` process (the plugin configured as a user would, subprocesses measured) calls a V+ program in
an in-process emulator and starts the shipped V+ server as an ``aioadept sim --vplus`` subprocess, sends it one
command and stops it; then ``coverage combine`` and ``coverage json``/``xml`` report the .V2 files beside the Python
script, line by line."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from aioadept.vplus.loader import Module, load_text

pytest.importorskip("coverage", reason="coverage.py (the test extra) is needed for V+ line coverage")

ROOT = Path(__file__).resolve().parents[2]

PROG = (".PROGRAM demo(n, r)\n"       # 1
        "; a comment\n"               # 2
        "    AUTO i\n"                # 3  a declaration: not a statement that runs
        "    r = 0\n"                 # 4
        "    FOR i = 1 TO n\n"        # 5
        "        IF i > 2 THEN\n"     # 6
        "            r = r+i\n"       # 7
        "        ELSE\n"              # 8
        "            r = r-1\n"       # 9
        "        END\n"               # 10
        "    END\n"                   # 11
        "    IF n > 100 THEN\n"       # 12
        "        TYPE \"big\"\n"      # 13 never runs
        "    END\n"                   # 14
        ".END\n"                      # 15
        ".PROGRAM never()\n"          # 16
        "    TYPE \"never\"\n"        # 17 never runs
        ".END\n")
RAN, MISSED = [4, 5, 6, 7, 9, 12], [13, 17]

SCRIPT = textwrap.dedent("""
    import socket, subprocess, sys, signal
    from aioadept.ports import free_port
    from aioadept.vplus import Emulator

    emu = Emulator.load("prog.V2", robot=False)
    assert emu.call("demo", 4, 0).args == (4.0, 5.0)

    port, stop_port = free_port(), free_port()
    vplus = [f"@ROOT@/vplus/{f}" for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]
    sim = subprocess.Popen([sys.executable, "-m", "aioadept.cli", "sim", "--vplus", *vplus, "--run", "rs.main",
                            "--map-port", f"1234={port}", "--map-port", f"1235={stop_port}",
                            "--state-endpoint", "none"], stdout=subprocess.PIPE, text=True)
    try:
        while not sim.stdout.readline().startswith("READY"):    # the V+ program's TYPE lines come first
            assert sim.poll() is None, "the sim ended before READY"
        with socket.create_connection(("127.0.0.1", port), timeout=30) as s:
            s.sendall(b"0000000a:hello\\r\\n")
            ack = s.makefile().readline()
        assert ack.startswith("0000000a:"), ack
    finally:
        sim.send_signal(signal.SIGINT)
        sim.wait(timeout=30)
""").replace("@ROOT@", str(ROOT))

RC = textwrap.dedent(f"""
    [run]
    plugins = aioadept.vplus.coverage_plugin
    patch = subprocess
    source = .
        {ROOT / "vplus"}
""")


def coverage(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    done = subprocess.run([sys.executable, "-m", "coverage", args[0], "--rcfile=covrc", *args[1:]], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    return done


def line_of(path: Path, code: str) -> int:
    """The line number of the first line of ``path`` that is ``code`` (indentation aside)."""
    return next(n for n, line in enumerate(path.read_text("latin-1").split("\n"), 1) if line.strip() == code)


def program_lines(path: Path, name: str) -> set[int]:
    prog = load_text(path.read_text("latin-1"), path.name, Module()).programs[name]
    return {line for line, _ in prog.steps}


@pytest.mark.timeout(120)
def test_coverage_reports_the_v2_lines_that_ran_in_process_and_in_an_aioadept_sim_subprocess(tmp_path):
    (tmp_path / "prog.V2").write_text(PROG)
    (tmp_path / "script.py").write_text(SCRIPT)
    (tmp_path / "covrc").write_text(RC)
    coverage(tmp_path, "run", "script.py")
    coverage(tmp_path, "combine")
    coverage(tmp_path, "json", "-o", "cov.json")
    files = json.loads((tmp_path / "cov.json").read_text())["files"]

    # the in-process emulator: exactly the statements that ran, beside the Python script
    assert files["prog.V2"]["executed_lines"] == RAN
    assert files["prog.V2"]["missing_lines"] == MISSED
    assert files["script.py"]["summary"]["percent_covered"] > 0

    # the server in the sim subprocess: its start, the reader's serving of hello; not the skills nobody called
    server = ROOT / "vplus" / "rserver.V2"
    by_name = {Path(name).name: data for name, data in files.items()}
    ran = set(by_name["rserver.V2"]["executed_lines"])
    assert {line_of(server, "CALL rs.init()"), line_of(server, "EXECUTE 2 rs.reader()"),
            line_of(server, "CALL rs.exec()")} <= ran
    assert ran & program_lines(server, "rs.reader") and ran & program_lines(server, "rs.exec")
    skills = ROOT / "vplus" / "rsskills.V2"
    assert not set(by_name["rsskills.V2"]["executed_lines"]) & program_lines(skills, "move_to")
    # a file of the measured folder that nothing loaded is reported too, every statement missed
    assert by_name["rsstate.V2"]["executed_lines"] == [] and by_name["rsstate.V2"]["missing_lines"]

    # the XML report (CI services read it) has the V+ file's lines with their hits
    coverage(tmp_path, "xml", "-o", "cov.xml")
    cls = next(c for c in ET.parse(tmp_path / "cov.xml").iter("class") if c.get("filename") == "prog.V2")
    hits = {int(ln.get("number")): int(ln.get("hits")) for ln in cls.iter("line")}
    assert hits == {**{n: 1 for n in RAN}, **{n: 0 for n in MISSED}}
